// kestrel run, end to end on a tiny generated scene: missing input frames (fail or skip),
// output folders checked before frame 1, --resume and --warmup.
#include <OpenEXR/ImfOutputFile.h>

#include <cmath>
#include <map>

#include "CliRunner.h"
#include "ExrCheck.h"

using namespace clitest;

namespace {

class CliRun : public ::testing::Test {
protected:
    void SetUp() override {
        // 32x24, 8 frames: about 0.1 s to generate, enough for warm-up and resume.
        if (!makeScene(box, box.work() / "scene", 32, 24, 8))
            GTEST_SKIP() << "no scenegen in this build";
    }
    CliResult run(const std::string& graph, std::vector<std::string> extra) {
        std::vector<std::string> args = {"run",       (graphDir() / graph).string(),
                                         "--input",   "scene/noisy/frame_####.exr",
                                         "--threads", "2"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    }
    /// Lines of the run log reporting a frame that was written (not warm-up).
    static int writtenFrameLines(const CliResult& r) {
        int n = 0;
        std::istringstream s(r.err);
        for (std::string l; std::getline(s, l);)
            if (l.find("frame ") != std::string::npos && l.find(" ms") != std::string::npos &&
                l.find("warm-up") == std::string::npos && l.find("frames run") == std::string::npos)
                ++n;
        return n;
    }
    Sandbox box;
};

}  // namespace

TEST_F(CliRun, RunsAndWritesEveryFrame) {
    auto r = run("copy.json", {"--frames", "1-3", "--output", "out/c.####.exr"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_TRUE(r.errorLines().empty()) << r.all();
    EXPECT_FALSE(looksLikeCrash(r.all()));
    EXPECT_EQ(countFiles(box.work() / "out", ".exr"), 3);
    RgbImage img;
    std::string why;
    ASSERT_TRUE(readRgb((box.work() / "out" / "c.0002.exr").string(), img, &why)) << why;
    EXPECT_EQ(img.width, 32);
    EXPECT_EQ(img.height, 24);
}

TEST_F(CliRun, MissingInputFrameFailsNamingFileAndFrame) {
    fs::remove(box.work() / "scene" / "noisy" / "frame_0003.exr");
    auto r = run("copy.json", {"--frames", "1-5", "--output", "out/c.####.exr"});
    EXPECT_EQ(r.code, 1) << r.all();
    auto lines = r.errorLines();
    ASSERT_EQ(lines.size(), 1u) << r.all();
    EXPECT_NE(lines[0].find("frame_0003.exr"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("frame 3"), std::string::npos) << lines[0];
    EXPECT_FALSE(looksLikeCrash(r.all()));
    // Frames before the gap were written and are complete; nothing after it.
    EXPECT_TRUE(fs::exists(box.work() / "out" / "c.0002.exr"));
    EXPECT_FALSE(fs::exists(box.work() / "out" / "c.0004.exr"));
    EXPECT_EQ(countTempFiles(box.work() / "out"), 0);
}

TEST_F(CliRun, SkipBadFramesContinues) {
    fs::remove(box.work() / "scene" / "noisy" / "frame_0003.exr");
    auto r =
        run("taa.json", {"--frames", "1-5", "--output", "out/t.####.exr", "--skip-bad-frames"});
    EXPECT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.err.find("frame_0003.exr"), std::string::npos) << "the skip is not reported\n"
                                                               << r.all();
    EXPECT_FALSE(looksLikeCrash(r.all()));
    for (int f : {1, 2, 4, 5})
        EXPECT_TRUE(fs::exists(box.work() / "out" / frameName("t.", f, ".exr"))) << f;
    EXPECT_FALSE(fs::exists(box.work() / "out" / "t.0003.exr"));
}

TEST_F(CliRun, UnwritableOutputFailsBeforeFrameOne) {
    // A regular file where the output folder should be: no process (not even root) can create
    // the folder, so this is portable where chmod is not.
    writeText(box.work() / "blocker", "not a folder");
    auto r = run("copy.json", {"--frames", "1-3", "--output", "blocker/sub/c.####.exr"});
    EXPECT_EQ(r.code, 1) << r.all();
    auto lines = r.errorLines();
    ASSERT_EQ(lines.size(), 1u) << r.all();
    EXPECT_NE(lines[0].find("blocker"), std::string::npos) << lines[0];
    // No frame ran: the per-frame log line for frame 1 never appears.
    EXPECT_EQ(writtenFrameLines(r), 0) << r.all();
    EXPECT_FALSE(looksLikeCrash(r.all()));
}

TEST_F(CliRun, ResumeSkipsWrittenFrames) {
    auto first = run("taa.json", {"--frames", "1-6", "--output", "out/t.####.exr"});
    ASSERT_EQ(first.code, 0) << first.all();
    ASSERT_EQ(countFiles(box.work() / "out", ".exr"), 6);
    // An interrupted run: frames 5 and 6 are missing. Date the survivors back so a rewrite shows.
    fs::remove(box.work() / "out" / "t.0005.exr");
    fs::remove(box.work() / "out" / "t.0006.exr");
    const auto old = fs::file_time_type::clock::now() - std::chrono::hours(1);
    for (int f = 1; f <= 4; ++f)
        fs::last_write_time(box.work() / "out" / frameName("t.", f, ".exr"), old);

    auto r = run("taa.json", {"--frames", "1-6", "--output", "out/t.####.exr", "--resume"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_EQ(writtenFrameLines(r), 2) << r.all();
    for (int f = 1; f <= 4; ++f)
        EXPECT_EQ(fs::last_write_time(box.work() / "out" / frameName("t.", f, ".exr")), old)
            << "frame " << f << " rewritten";
    EXPECT_EQ(countFiles(box.work() / "out", ".exr"), 6);

    // History was warmed up on frames 1-4, so the resumed frames equal the uninterrupted run's.
    auto full = run("taa.json", {"--frames", "1-6", "--output", "full/t.####.exr"});
    ASSERT_EQ(full.code, 0) << full.all();
    for (int f : {5, 6}) {
        RgbImage a, b;
        ASSERT_TRUE(readRgb((box.work() / "out" / frameName("t.", f, ".exr")).string(), a));
        ASSERT_TRUE(readRgb((box.work() / "full" / frameName("t.", f, ".exr")).string(), b));
        ASSERT_EQ(a.rgb.size(), b.rgb.size());
        for (size_t i = 0; i < a.rgb.size(); ++i)
            ASSERT_EQ(a.rgb[i], b.rgb[i]) << "frame " << f << " value " << i;
    }

    // Everything written: nothing to do, still success.
    auto again = run("taa.json", {"--frames", "1-6", "--output", "out/t.####.exr", "--resume"});
    EXPECT_EQ(again.code, 0) << again.all();
    EXPECT_EQ(writtenFrameLines(again), 0) << again.all();
}

TEST_F(CliRun, WarmupChunkMatchesUnsplitRun) {
    // TAA carries history from frame to frame. A chunk 5-8 with --warmup 4 replays frames 1-4
    // without writing them, so frames 5-8 see exactly the history of the unsplit run 1-8.
    auto whole = run("taa.json", {"--frames", "1-8", "--output", "whole/t.####.exr"});
    ASSERT_EQ(whole.code, 0) << whole.all();
    auto chunk =
        run("taa.json", {"--frames", "5-8", "--warmup", "4", "--output", "chunk/t.####.exr"});
    ASSERT_EQ(chunk.code, 0) << chunk.all();
    EXPECT_EQ(countFiles(box.work() / "chunk", ".exr"), 4) << "warm-up frames must not be written";
    EXPECT_FALSE(fs::exists(box.work() / "chunk" / "t.0004.exr"));

    // Tolerance: 0. Same frames, same order, same float operations, and results never depend on
    // the thread count (team rule), so the written float32 files must be bit-identical. Any
    // difference means the warm-up did not rebuild the history (e.g. a short warm-up or reset).
    // Without warm-up the chunk differs (checked below), so this comparison has teeth.
    double maxDiff = 0;
    for (int f = 5; f <= 8; ++f) {
        RgbImage a, b;
        ASSERT_TRUE(readRgb((box.work() / "whole" / frameName("t.", f, ".exr")).string(), a));
        ASSERT_TRUE(readRgb((box.work() / "chunk" / frameName("t.", f, ".exr")).string(), b));
        ASSERT_EQ(a.rgb.size(), b.rgb.size());
        for (size_t i = 0; i < a.rgb.size(); ++i)
            maxDiff = std::max(maxDiff, double(std::fabs(a.rgb[i] - b.rgb[i])));
    }
    EXPECT_EQ(maxDiff, 0.0);

    auto cold = run("taa.json", {"--frames", "5-8", "--output", "cold/t.####.exr"});
    ASSERT_EQ(cold.code, 0) << cold.all();
    RgbImage a, b;
    ASSERT_TRUE(readRgb((box.work() / "whole" / "t.0005.exr").string(), a));
    ASSERT_TRUE(readRgb((box.work() / "cold" / "t.0005.exr").string(), b));
    double coldDiff = 0;
    for (size_t i = 0; i < a.rgb.size(); ++i)
        coldDiff = std::max(coldDiff, double(std::fabs(a.rgb[i] - b.rgb[i])));
    EXPECT_GT(coldDiff, 1e-3)
        << "without warm-up frame 5 should differ (1-spp noise is not averaged)";
}

// The default log is a few lines before the first frame (notes grouped, the left-out passes
// counted with the absent inputs that caused them); -v still lists every pass left out.
TEST_F(CliRun, DefaultLogIsShortAndVerboseHasEveryDetail) {
    auto runSvgf = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = {
            "run",      std::string(KESTREL_SOURCE_DIR) + "/graphs/svgf.json",
            "--input",  "scene/noisy/frame_####.exr",
            "--output", "out/s.####.exr",
            "--frames", "1-2"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    };
    auto linesBeforeFrameOne = [](const std::string& log) {
        std::istringstream s(log);
        int n = 0;
        for (std::string l; std::getline(s, l) && l.find("frame 1 (") == std::string::npos;) ++n;
        return n;
    };
    const CliResult quiet = runSvgf({});
    ASSERT_EQ(quiet.code, 0) << quiet.all();
    EXPECT_LE(linesBeforeFrameOne(quiet.err), 10) << quiet.err;
    EXPECT_EQ(quiet.err.find("pruned "), std::string::npos) << quiet.err;
    EXPECT_NE(quiet.err.find("left out "), std::string::npos) << quiet.err;
    EXPECT_NE(quiet.err.find("input.diffuse"), std::string::npos) << quiet.err;  // a cause
    const CliResult verbose = runSvgf({"-v"});
    ASSERT_EQ(verbose.code, 0) << verbose.all();
    EXPECT_NE(verbose.err.find("pruned diffuse.demodulate: "), std::string::npos) << verbose.err;
}

// A render with many passes (the street: the split, the light passes) logs short lines: the
// loader's plain output mappings are counted and its channel names listed only with -v (the
// first log line of a Blender render was ~1,100 characters, the channel list ~900).
TEST_F(CliRun, DefaultLogLinesStayShortOnARenderWithManyPasses) {
    ASSERT_EQ(box.run({"scenegen", "--scene", "street", "--out", "street", "--width", "48",
                       "--height", "32", "--frames", "1"})
                  .code,
              0);
    auto runSvgf = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = {
            "run", std::string(KESTREL_SOURCE_DIR) + "/graphs/svgf.json", "--input",
            "street/noisy/frame_####.exr", "--output", "out/t.####.exr"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    };
    const CliResult quiet = runSvgf({});
    ASSERT_EQ(quiet.code, 0) << quiet.all();
    std::istringstream lines(quiet.err);
    for (std::string l; std::getline(lines, l);) EXPECT_LE(l.size(), 300u) << l;
    EXPECT_NE(quiet.err.find("more outputs read as named (-v lists them)"), std::string::npos)
        << quiet.err;
    const CliResult verbose = runSvgf({"-v"});
    ASSERT_EQ(verbose.code, 0) << verbose.all();
    EXPECT_NE(verbose.err.find("ExrLoader: channels read: "), std::string::npos) << verbose.err;
    EXPECT_NE(verbose.err.find("depth = depth.Z"), std::string::npos) << verbose.err;
}

// --dump writes every frame of each matching resource as a float EXR (pass.port.####.exr under
// --dump-dir) and changes nothing else: the output is the same to the bit with every resource
// dumped (each stays alive until its writer has it, so no in-place output may overwrite it),
// and the dumped final colour is the output. A pattern that matches nothing is refused.
TEST_F(CliRun, DumpWritesMatchingResourcesAndChangesNothing) {
    auto runSvgf = [&](const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> args = {
            "run",      std::string(KESTREL_SOURCE_DIR) + "/graphs/svgf.json",
            "--input",  "scene/noisy/frame_####.exr",
            "--output", out + "/s.####.exr",
            "--set",    "output.pixelType=float",
            "--frames", "1-3"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    };
    const CliResult plain = runSvgf("plain", {});
    ASSERT_EQ(plain.code, 0) << plain.all();
    const CliResult dumped = runSvgf("dumped", {"--dump", "*", "--dump-dir", "d"});
    ASSERT_EQ(dumped.code, 0) << dumped.all();
    EXPECT_EQ(countFiles(box.work() / "d", ".exr"), 3 * countFiles(box.work() / "d", ".0001.exr"));
    EXPECT_GT(countFiles(box.work() / "d", ".0001.exr"), 20);  // every live resource
    for (int f = 1; f <= 3; ++f) {
        RgbImage a, b, d;
        const std::string name = frameName("s.", f, ".exr");
        ASSERT_TRUE(readRgb((box.work() / "plain" / name).string(), a));
        ASSERT_TRUE(readRgb((box.work() / "dumped" / name).string(), b));
        ASSERT_TRUE(readRgb(
            (box.work() / "d" / frameName("single.modulate.color.", f, ".exr")).string(), d));
        EXPECT_EQ(a.rgb, b.rgb) << "frame " << f;
        EXPECT_EQ(d.rgb, a.rgb) << "frame " << f;  // the room: no TAA, the modulated colour
    }
    const CliResult typo = runSvgf("typo", {"--dump", "*atrous9.color"});
    EXPECT_EQ(typo.code, 2) << typo.all();
    EXPECT_NE(typo.err.find("--dump '*atrous9.color' matches no resource"), std::string::npos)
        << typo.err;
}

namespace {
/// Rewrites `file` with an A channel (of R's type): 0.25 on the left half, 1 on the right.
void addAlpha(const fs::path& file) {
    Imf::Header header;
    std::map<std::string, std::vector<float>> data;
    int W = 0, H = 0;
    {
        Imf::InputFile in(file.c_str());
        header = in.header();
        const Imath::Box2i dw = header.dataWindow();
        W = dw.max.x - dw.min.x + 1;
        H = dw.max.y - dw.min.y + 1;
        Imf::FrameBuffer fb;
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
            auto& v = data[it.name()];
            v.resize(size_t(W) * size_t(H));
            fb.insert(it.name(), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(v.data()),
                                            sizeof(float), sizeof(float) * size_t(W)));
        }
        in.setFrameBuffer(fb);
        in.readPixels(dw.min.y, dw.max.y);
    }
    header.channels().insert("A", Imf::Channel(header.channels().findChannel("R")->type));
    auto& a = data["A"];
    a.resize(size_t(W) * size_t(H));
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) a[size_t(y) * size_t(W) + size_t(x)] = x < W / 2 ? 0.25f : 1.f;
    Imf::FrameBuffer fb;
    for (auto& [name, v] : data)
        fb.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(v.data()), sizeof(float),
                                   sizeof(float) * size_t(W)));
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(fb);
    out.writePixels(H);
}

/// Channel `name` of `file` as floats, empty when the file has no such channel.
std::vector<float> channelOf(const fs::path& file, const std::string& name) {
    Imf::InputFile in(file.c_str());
    if (!in.header().channels().findChannel(name)) return {};
    const Imath::Box2i dw = in.header().dataWindow();
    const size_t W = size_t(dw.max.x - dw.min.x + 1), H = size_t(dw.max.y - dw.min.y + 1);
    std::vector<float> v(W * H);
    Imf::FrameBuffer fb;
    fb.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(v.data()), sizeof(float),
                               sizeof(float) * W));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    return v;
}
}  // namespace

// The shipped graph keeps the input's alpha: the output's A is the input's, unfiltered; an input
// without alpha gives an output without an A channel.
TEST_F(CliRun, ShippedGraphKeepsTheInputsAlpha) {
    const fs::path svgf = fs::path(KESTREL_SOURCE_DIR) / "graphs" / "svgf.json";
    auto runSvgf = [&](const std::string& out) {
        return box.run({"run", svgf.string(), "--input", "scene/noisy/frame_####.exr", "--output",
                        out + "/frame_####.exr", "--frames", "1-2", "--threads", "2"});
    };
    CliResult plain = runSvgf("plain");
    ASSERT_EQ(plain.code, 0) << plain.all();
    EXPECT_TRUE(channelOf(box.work() / "plain" / "frame_0002.exr", "A").empty());

    for (int f = 1; f <= 2; ++f)
        addAlpha(box.work() / "scene" / "noisy" / frameName("frame_", f, ".exr"));
    CliResult r = runSvgf("alpha");
    ASSERT_EQ(r.code, 0) << r.all();
    const auto in = channelOf(box.work() / "scene" / "noisy" / "frame_0002.exr", "A");
    const auto out = channelOf(box.work() / "alpha" / "frame_0002.exr", "A");
    ASSERT_EQ(out.size(), in.size());
    EXPECT_EQ(out, in);
    EXPECT_EQ(out.front(), 0.25f);
    EXPECT_EQ(out.back(), 1.f);
    // The colour is the same as without alpha: A is carried beside it, not mixed in.
    EXPECT_EQ(channelOf(box.work() / "alpha" / "frame_0002.exr", "G"),
              channelOf(box.work() / "plain" / "frame_0002.exr", "G"));
}
