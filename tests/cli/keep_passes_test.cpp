// kestrel run --keep-passes (ExrWriter keepPasses): the output EXR carries the input's other
// channels and its header attributes beside the denoised colour, so a compositor keeps the
// render's AOVs; the inputs are only read.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <set>

#include "CliRunner.h"

using namespace clitest;

namespace {

std::set<std::string> channelNames(const fs::path& file) {
    Imf::InputFile in(file.c_str());
    std::set<std::string> names;
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it)
        names.insert(it.name());
    return names;
}

std::vector<float> pixels(const fs::path& file, const std::string& name) {
    Imf::InputFile in(file.c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    const size_t W = size_t(dw.max.x - dw.min.x + 1), H = size_t(dw.max.y - dw.min.y + 1);
    std::vector<float> v(W * H);
    Imf::FrameBuffer fb;
    fb.insert(name, Imf::Slice::Make(Imf::FLOAT, v.data(), dw));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    return v;
}

std::string stringAttribute(const fs::path& file, const std::string& name) {
    Imf::InputFile in(file.c_str());
    const auto* a = in.header().findTypedAttribute<Imf::StringAttribute>(name);
    return a ? a->value() : "";
}

/// Rewrites `file` with the render statistics a renderer puts in its header.
void addRenderAttributes(const fs::path& file) {
    Imf::Header header;
    std::map<std::string, std::vector<float>> data;
    Imath::Box2i dw;
    {
        Imf::InputFile in(file.c_str());
        header = in.header();
        dw = header.dataWindow();
        Imf::FrameBuffer fb;
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
            auto& v = data[it.name()];
            v.resize(size_t(dw.max.x - dw.min.x + 1) * size_t(dw.max.y - dw.min.y + 1));
            fb.insert(it.name(), Imf::Slice::Make(Imf::FLOAT, v.data(), dw));
        }
        in.setFrameBuffer(fb);
        in.readPixels(dw.min.y, dw.max.y);
    }
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
        it.channel().type = Imf::FLOAT;
    header.insert("renderTime", Imf::StringAttribute("00:01.50"));
    header.insert("cameraName", Imf::StringAttribute("shotCam"));
    Imf::FrameBuffer fb;
    for (auto& [name, v] : data) fb.insert(name, Imf::Slice::Make(Imf::FLOAT, v.data(), dw));
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(fb);
    out.writePixels(dw.max.y - dw.min.y + 1);
}

fs::path shippedGraph(const std::string& name) {
    return fs::path(KESTREL_SOURCE_DIR) / "graphs" / name;
}

fs::path sharedData(const std::string& name) {
    const fs::path dir = fs::path(KESTREL_SOURCE_DIR) / ".." / "shared" / "data" / name;
    std::error_code ec;
    return fs::exists(dir, ec) ? dir : fs::path();
}

}  // namespace

TEST(KeepPasses, OutputCarriesTheInputsOtherChannelsAndHeader) {
    Sandbox box;
    if (!makeScene(box, box.work() / "scene", 32, 24, 2)) GTEST_SKIP() << "no scenegen";
    const fs::path noisy = box.work() / "scene" / "noisy";
    for (int f = 1; f <= 2; ++f) addRenderAttributes(noisy / frameName("frame_", f, ".exr"));
    const auto before = checksums(box.work() / "scene");
    const std::vector<std::string> args = {"run",
                                           shippedGraph("svgf.json").string(),
                                           "--input",
                                           "scene/noisy/frame_####.exr",
                                           "--output",
                                           "out/frame_####.exr",
                                           "--keep-passes",
                                           "--threads",
                                           "2"};
    CliResult r = box.run(args);
    ASSERT_EQ(r.code, 0) << r.all();

    const fs::path in = noisy / "frame_0002.exr", out = box.work() / "out" / "frame_0002.exr";
    // Every channel: the input's colour (R, G, B) replaced by the denoised one, the rest kept.
    EXPECT_EQ(channelNames(out), channelNames(in));
    for (const char* aov : {"depth.Z", "motion.X", "normal.Y", "albedo.G", "objectId.id"})
        EXPECT_EQ(pixels(out, aov), pixels(in, aov)) << aov;
    EXPECT_NE(pixels(out, "G"), pixels(in, "G"));
    EXPECT_EQ(stringAttribute(out, "renderTime"), "00:01.50");
    EXPECT_EQ(stringAttribute(out, "cameraName"), "shotCam");
    EXPECT_FALSE(stringAttribute(out, "kestrel.provenance").empty());
    EXPECT_EQ(checksums(box.work() / "scene"), before) << "an input file changed";

    // The output is intact for --resume (its checksum and provenance are the run's).
    std::vector<std::string> resume = args;
    resume.push_back("--resume");
    CliResult again = box.run(resume);
    ASSERT_EQ(again.code, 0) << again.all();
    EXPECT_NE(again.err.find("every frame is already written"), std::string::npos) << again.all();

    // Without the option the output is the colour alone.
    CliResult plain =
        box.run({"run", shippedGraph("svgf.json").string(), "--input", "scene/noisy/frame_####.exr",
                 "--output", "plain/frame_####.exr", "--frames", "1-1"});
    ASSERT_EQ(plain.code, 0) << plain.all();
    EXPECT_EQ(channelNames(box.work() / "plain" / "frame_0001.exr"),
              (std::set<std::string>{"B", "G", "R"}));
}

TEST(KeepPasses, BlenderRenderKeepsItsPassesButNotItsNoisyCombined) {
    const fs::path street = sharedData("blender-street");
    if (street.empty()) GTEST_SKIP() << "../shared/data/blender-street not present";
    Sandbox box;
    CliResult r = box.run({"run", shippedGraph("svgf.json").string(), "--input",
                           (street / "noisy" / "frame_####.exr").string(), "--output",
                           "out/frame_####.exr", "--frames", "1-1", "--keep-passes"});
    ASSERT_EQ(r.code, 0) << r.all();
    const fs::path in = street / "noisy" / "frame_0001.exr";
    const fs::path out = box.work() / "out" / "frame_0001.exr";
    const auto names = channelNames(out);
    for (const char* c : {"R", "G", "B", "A", "ViewLayer.Depth.Z", "ViewLayer.Vector.W",
                          "ViewLayer.DiffCol.R", "ViewLayer.Denoising Albedo.B"})
        EXPECT_TRUE(names.count(c)) << c;
    for (const char* c : {"ViewLayer.Combined.R", "ViewLayer.Combined.A"})
        EXPECT_FALSE(names.count(c)) << c << ": the noisy colour and its alpha are replaced";
    EXPECT_EQ(pixels(out, "ViewLayer.Depth.Z"), pixels(in, "ViewLayer.Depth.Z"));
    EXPECT_EQ(names.size(), channelNames(in).size());
}

TEST(KeepPasses, RefusedWhereNoFileHoldsTheFramesPasses) {
    const fs::path box202 = sharedData("games202-box");
    if (box202.empty()) GTEST_SKIP() << "../shared/data/games202-box not present";
    Sandbox box;
    CliResult r =
        box.run({"run", shippedGraph("games202-jbf.json").string(), "--input", box202.string(),
                 "--output", "out/frame_####.exr", "--frames", "0-1", "--keep-passes"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"keepPasses", "output"});
}
