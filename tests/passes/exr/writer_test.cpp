// ExrWriter: atomic writes, half-range clamping, provenance, previews, run-start checks.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <gtest/gtest.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include "ExrWriter.h"
#include "ZipWriter.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::Format;
using kestrel::Image;
using kestrel::exr::ExrWriter;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {
std::vector<std::string> listing(const fs::path& dir) {
    std::vector<std::string> names;
    for (auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

PassHarness writer(const fs::path& dir, std::map<std::string, kestrel::ParamValue> extra = {}) {
    extra["path"] = (dir / "out.####.exr").string();
    return PassHarness::make<ExrWriter>({4, 2}, extra);
}

void beginRun(PassHarness& h, int64_t first) {
    kestrel::RunInfo info;
    kestrel::RunContext rc{&info, first, first};
    h.pass().beginRun(rc);
}
}  // namespace

TEST(ExrWriter, HalfClampsOutOfRangeAndNaNWithoutInf) {
    TempDir tmp("wclamp");
    Image img(4, 2, Format::Float3);
    img.at(0, 0, 0) = 1e6f;
    img.at(1, 1, 0) = -1e9f;
    img.at(2, 2, 0) = std::numeric_limits<float>::infinity();
    img.at(0, 3, 1) = std::numeric_limits<float>::quiet_NaN();
    img.at(1, 3, 1) = 0.333f;
    auto h = writer(tmp.path, {{"pixelType", std::string("half")}});
    beginRun(h, 5);
    h.bind("color", img);
    h.ctx.frameNumber = 5;
    h.run();
    auto file = tmp.path / "out.0005.exr";
    auto R = readChannel(file, "R"), G = readChannel(file, "G"), B = readChannel(file, "B");
    EXPECT_EQ(R[0], 65504.f);
    EXPECT_EQ(G[1], -65504.f);
    EXPECT_EQ(B[2], 65504.f);
    EXPECT_EQ(R[7], 0.f);
    EXPECT_NEAR(G[7], 0.333f, 2e-4f);  // half precision
    for (auto* ch : {&R, &G, &B})
        for (float v : *ch) EXPECT_TRUE(std::isfinite(v));
    Imf::InputFile in(file.c_str());
    EXPECT_EQ(in.header().channels().findChannel("R")->type, Imf::HALF);
}

/// pixelType auto keeps the source's precision: float unless the source states half colour.
static Imf::PixelType writtenType(std::optional<std::string> sourceColor) {
    TempDir tmp("wauto");
    Image img(4, 2, Format::Float3);
    img.fill(1.f + 1.f / 4096.f);  // between two halves: only float keeps it
    auto h = writer(tmp.path);
    RecordingResolve rc(1);
    if (sourceColor) rc.facts["colorPixelType"] = *sourceColor;
    h.pass().resolve(rc);
    beginRun(h, 1);
    h.bind("color", img);
    h.ctx.frameNumber = 1;
    h.run();
    Imf::InputFile in((tmp.path / "out.0001.exr").c_str());
    return in.header().channels().findChannel("R")->type;
}

TEST(ExrWriter, AutoPixelTypeKeepsTheSourcesPrecision) {
    EXPECT_EQ(writtenType(std::nullopt), Imf::FLOAT);  // no source statement: lose nothing
    EXPECT_EQ(writtenType("float"), Imf::FLOAT);
    EXPECT_EQ(writtenType("half"), Imf::HALF);
}

TEST(ExrWriter, AtomicNoTemporaryLeftAndProvenanceStored) {
    TempDir tmp("watomic");
    Image img(4, 2, Format::Float);
    img.fill(0.5f);
    auto h = writer(tmp.path,
                    {{"pixelType", std::string("float")}, {"compression", std::string("piz")}});
    beginRun(h, 1);
    h.bind("color", img);
    h.ctx.frameNumber = 1;
    h.run();
    h.run();
    EXPECT_EQ(listing(tmp.path), (std::vector<std::string>{"out.0001.exr", "out.0002.exr"}));
    Imf::InputFile in((tmp.path / "out.0001.exr").c_str());
    auto* graph = in.header().findTypedAttribute<Imf::StringAttribute>("kestrel.graph");
    ASSERT_NE(graph, nullptr);
    EXPECT_EQ(graph->value(), "test");
    EXPECT_NE(in.header().findTypedAttribute<Imf::StringAttribute>("kestrel.provenance"), nullptr);
    EXPECT_EQ(in.header().channels().findChannel("R")->type, Imf::FLOAT);
    EXPECT_EQ(in.header().compression(), Imf::PIZ_COMPRESSION);
    EXPECT_TRUE(h.pass().frameWritten(2, ""));
    EXPECT_FALSE(h.pass().frameWritten(3, ""));
}

TEST(ExrWriter, FailedWriteLeavesNoPartialFile) {
    TempDir tmp("wfail");
    fs::create_directories(tmp.path / "out.0001.exr");  // the rename target cannot be replaced
    Image img(4, 2, Format::Float3);
    auto h = writer(tmp.path);
    h.bind("color", img);
    h.ctx.frameNumber = 1;
    EXPECT_THROW(h.run(), kestrel::Error);
    EXPECT_EQ(listing(tmp.path), (std::vector<std::string>{"out.0001.exr"}));
    EXPECT_TRUE(fs::is_directory(tmp.path / "out.0001.exr"));
}

// Issue 40 item 12: a failed write said "cannot create the file" or "writing failed (disk
// full?)" without the system's reason; now errno's words, for the EXR and its preview.
TEST(ExrWriter, FailedWriteSaysTheSystemsReason) {
    TempDir tmp("wreason");
    Image img(4, 2, Format::Float3);
    auto h = PassHarness::make<ExrWriter>(
        {4, 2}, {{"path", (tmp.path / "exr" / "out.####.exr").string()},
                 {"preview", (tmp.path / "png" / "prev.####.png").string()}});
    beginRun(h, 1);
    h.bind("color", img);
    h.ctx.frameNumber = 1;
    auto messageOf = [&] {
        try {
            h.run();
        } catch (const kestrel::Error& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    const std::string noFolder = std::strerror(ENOENT);
    fs::remove_all(tmp.path / "exr");  // the folder went away after the run started
    EXPECT_NE(messageOf().find("cannot create the file: " + noFolder), std::string::npos)
        << messageOf();
    fs::create_directories(tmp.path / "exr");
    fs::remove_all(tmp.path / "png");
    const std::string png = messageOf();
    EXPECT_NE(png.find("cannot create PNG "), std::string::npos) << png;
    EXPECT_NE(png.find(": " + noFolder), std::string::npos) << png;
    // A write that fails after the open: the disk is full.
    if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
    Imf::Header header(4, 2);
    header.compression() = Imf::ZIP_COMPRESSION;
    header.channels().insert("R", Imf::Channel(Imf::FLOAT));
    std::vector<float> r(8, 0.5f);
    try {
        kestrel::exr::writeZipScanlines("/dev/full", header, {r.data()}, 1, 4);
        FAIL() << "no error writing to /dev/full";
    } catch (const std::exception& e) {
        EXPECT_NE(std::string(e.what()).find(std::strerror(ENOSPC)), std::string::npos) << e.what();
    }
}

TEST(ExrWriter, UnwritableDirectoryFailsInBeginRun) {
    TempDir tmp("wdir");
    std::ofstream(tmp.path / "afile") << "x";  // a file where a folder should be (root-proof)
    auto h = PassHarness::make<ExrWriter>(
        {4, 2}, {{"path", (tmp.path / "afile" / "sub" / "f.####.exr").string()}});
    try {
        beginRun(h, 1);
        FAIL() << "no error";
    } catch (const kestrel::Error& e) {
        EXPECT_NE(std::string(e.what()).find((tmp.path / "afile" / "sub").string()),
                  std::string::npos)
            << e.what();
    }
    // beginRun creates a missing folder.
    auto ok = PassHarness::make<ExrWriter>({4, 2},
                                           {{"path", (tmp.path / "new/deeper/f.#.exr").string()}});
    beginRun(ok, 1);
    EXPECT_TRUE(fs::is_directory(tmp.path / "new/deeper"));
    EXPECT_TRUE(listing(tmp.path / "new/deeper").empty());
}

TEST(ExrWriter, PngPreviewWritten) {
    TempDir tmp("wpng");
    Image img(4, 2, Format::Float3);
    img.fill(0.18f);
    auto h =
        writer(tmp.path, {{"preview", (tmp.path / "prev.####.png").string()}, {"exposure", 1.0}});
    beginRun(h, 3);
    h.bind("color", img);
    h.ctx.frameNumber = 3;
    h.run();
    std::ifstream in(tmp.path / "prev.0003.png", std::ios::binary);
    std::vector<unsigned char> b((std::istreambuf_iterator<char>(in)),
                                 std::istreambuf_iterator<char>());
    ASSERT_GT(b.size(), 33u);
    EXPECT_EQ(std::vector<unsigned char>(b.begin(), b.begin() + 4),
              (std::vector<unsigned char>{0x89, 'P', 'N', 'G'}));
    EXPECT_EQ(b[19], 4u);  // IHDR width (big-endian) = 4
    EXPECT_EQ(b[23], 2u);  // height = 2
    EXPECT_EQ(listing(tmp.path), (std::vector<std::string>{"out.0003.exr", "prev.0003.png"}));
    // ACES fit of 0.36 then sRGB: the documented curve, not a clamp.
    EXPECT_NEAR(kestrel::display::toneMap(0.36f, kestrel::display::ToneCurve::Aces),
                0.36f * (2.51f * 0.36f + 0.03f) / (0.36f * (2.43f * 0.36f + 0.59f) + 0.14f), 1e-6f);
    EXPECT_EQ(kestrel::display::toneMap(std::nanf(""), kestrel::display::ToneCurve::Reinhard), 0.f);
}

TEST(ExrWriter, IdsAsFloatAndNothingWrittenDuringWarmup) {
    TempDir tmp("wids");
    Image ids(4, 2, Format::Int32);
    ids.atInt(1, 0) = 70000;  // beyond half's exact integers
    ids.atInt(2, 1) = -1;
    auto h = writer(tmp.path);
    h.bind("color", ids);
    h.ctx.frameNumber = 1;
    h.ctx.writeOutputs = false;
    h.run();
    EXPECT_TRUE(listing(tmp.path).empty());
    h.ctx.writeOutputs = true;
    h.run();  // frame 2
    auto id = readChannel(tmp.path / "out.0002.exr", "id");
    EXPECT_EQ(id[1], 70000.f);
    EXPECT_EQ(id[6], -1.f);
}

// The colour output states its colour space (OpenEXR's chromaticities: Rec.709 primaries, D65
// white) with every compression path (ZIP is written by kestrel's own encoder); ids have none.
TEST(ExrWriter, ColourOutputCarriesRec709Chromaticities) {
    for (const char* compression : {"zip", "piz"}) {
        TempDir tmp("wchroma");
        Image img(4, 2, Format::Float3);
        img.fill(0.25f);
        auto h = writer(tmp.path, {{"compression", std::string(compression)}});
        h.bind("color", img);
        h.ctx.frameNumber = 1;
        h.run();
        Imf::InputFile in((tmp.path / "out.0001.exr").c_str());
        ASSERT_TRUE(Imf::hasChromaticities(in.header())) << compression;
        const Imf::Chromaticities& c = Imf::chromaticities(in.header());
        EXPECT_EQ(c.red, Imath::V2f(0.64f, 0.33f)) << compression;
        EXPECT_EQ(c.green, Imath::V2f(0.30f, 0.60f)) << compression;
        EXPECT_EQ(c.blue, Imath::V2f(0.15f, 0.06f)) << compression;
        EXPECT_EQ(c.white, Imath::V2f(0.3127f, 0.3290f)) << compression;
    }
    TempDir tmp("wchromaid");
    Image ids(4, 2, Format::Int32);
    auto h = writer(tmp.path);
    h.bind("color", ids);
    h.ctx.frameNumber = 1;
    h.run();
    Imf::InputFile in((tmp.path / "out.0001.exr").c_str());
    EXPECT_FALSE(Imf::hasChromaticities(in.header()));
}
