// Issue 40, "Nothing lost anywhere": the inputs an adversarial user gives every command (JSON
// nested 55,000 levels, keys written twice, a FIFO where a file is expected, ...). Each case
// checks the documented exit code (docs/errors.md), the one error line and what it names, and
// that no input changed.
#include <OpenEXR/ImfOutputFile.h>
#include <sys/stat.h>

#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "CliRunner.h"
#include "ExrCheck.h"

using namespace clitest;

namespace {

/// tests/cli/graphs/copy.json with `tonemapParams` as the tone map's parameters (JSON text).
std::string copyGraphWith(const std::string& tonemapParams) {
    return R"({"kestrel": 1, "name": "copy", "passes": [
  {"name": "input", "type": "ExrLoader", "params": {}},
  {"name": "tonemap", "type": "ToneMap", "params": )" +
           tonemapParams + R"(},
  {"name": "output", "type": "ExrWriter", "params": {"path": "out/copy.####.exr"}}],
 "edges": [{"from": "input.color", "to": "tonemap.color"},
           {"from": "tonemap.color", "to": "output.color"}]})";
}

/// `[[[...0...]]]`, `levels` deep: 55,000 levels (110 KB) overflowed the stack of every command.
std::string nested(int levels) {
    return std::string(size_t(levels), '[') + "0" + std::string(size_t(levels), ']');
}

class CliNothingLost : public ::testing::Test {
protected:
    void SetUp() override {
        // 32x24, 3 frames: about 0.05 s to generate.
        if (!makeScene(box, box.work() / "scene", 32, 24, 3))
            GTEST_SKIP() << "no scenegen in this build";
        before = checksums(box.work() / "scene");
    }
    std::vector<std::string> runArgs(const std::string& graph, std::vector<std::string> extra) {
        std::vector<std::string> args = {
            "run", graph, "--input", "scene/noisy/frame_####.exr", "--threads", "2"};
        args.insert(args.end(), extra.begin(), extra.end());
        return args;
    }
    void expectInputsUntouched() {
        EXPECT_EQ(checksums(box.work() / "scene"), before) << "an input frame changed";
    }
    fs::path work() const { return box.work(); }

    Sandbox box;
    std::map<std::string, uint64_t> before;
};

// --- JSON: depth and duplicate keys, checked where every JSON text is parsed --------------

TEST_F(CliNothingLost, DeeplyNestedJsonIsRefusedByEveryCommand) {
    writeText(work() / "deep" / "deep.json",
              copyGraphWith(R"({"exposure": )" + nested(55000) + "}"));
    const std::vector<std::vector<std::string>> commands = {
        {"validate", "deep/deep.json"},
        {"graph", "deep/deep.json", "--dot"},
        runArgs("deep/deep.json", {"--frames", "1", "--output", "out/c.####.exr"}),
        {"passes", "--graphs", "deep"},
        {"bench", "deep/deep.json", "--input", "scene/noisy/frame_####.exr"},
    };
    for (const auto& args : commands) {
        SCOPED_TRACE(args[0]);
        auto r = box.runWithin(60, args);
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(
            r, {"deep.json", "nested deeper than 256 levels", "passes[1].params.exposure[0]"});
    }
    EXPECT_FALSE(fs::exists(work() / "out"));
    expectInputsUntouched();
}

TEST_F(CliNothingLost, DeeplyNestedSetValueIsRefused) {
    auto r = box.runWithin(60, runArgs((graphDir() / "copy.json").string(),
                                       {"--frames", "1", "--output", "out/c.####.exr", "--set",
                                        "tonemap.exposure=" + nested(50000)}));
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"--set tonemap.exposure", "nested deeper than 256 levels"});
    EXPECT_FALSE(fs::exists(work() / "out"));
}

TEST_F(CliNothingLost, NestingWithinTheLimitIsOnlyAParameterError) {
    writeText(work() / "ok.json", copyGraphWith(R"({"exposure": )" + nested(200) + "}"));
    auto r = box.run({"validate", "ok.json"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"passes[1].params.exposure", "expected number"});
}

TEST_F(CliNothingLost, DuplicateKeyIsRefusedWithItsJsonPath) {
    writeText(work() / "dup.json", copyGraphWith(R"({"exposure": 0.0, "exposure": 2.0})"));
    for (const auto& args : std::vector<std::vector<std::string>>{
             {"validate", "dup.json"},
             runArgs("dup.json", {"--frames", "1", "--output", "out/c.####.exr"})}) {
        SCOPED_TRACE(args[0]);
        auto r = box.run(args);
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {"dup.json", "duplicate key 'exposure'", "passes[1].params.exposure"});
    }
    EXPECT_FALSE(fs::exists(work() / "out"));
}

TEST_F(CliNothingLost, DuplicateKeyInAFarmPlanIsRefused) {
    writeText(work() / "plan.json", R"({"tasks": [], "tasks": []})");
    auto r = box.run({"farm", "check", "--plan", "plan.json"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"plan.json", "duplicate key 'tasks'"});
}

// --- readers refuse what is not a regular file (a FIFO blocked the read forever) ----------

/// A FIFO at `p` that nobody writes: opening it for reading blocks.
void makeFifo(const fs::path& p) {
    fs::create_directories(p.parent_path());
    ASSERT_EQ(::mkfifo(p.c_str(), 0600), 0) << p;
}

TEST_F(CliNothingLost, FifoAsReferenceIsRefused) {
    makeFifo(work() / "ref" / "frame_0001.exr");
    auto r = box.runWithin(30, runArgs((graphDir() / "copy.json").string(),
                                       {"--frames", "1", "--output", "out/c.####.exr",
                                        "--reference", "ref/frame_####.exr"}));
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"ref/frame_0001.exr", "not a regular file"});

    auto c = box.runWithin(30, {"compare", "scene/noisy/frame_0001.exr", "ref/frame_0001.exr"});
    EXPECT_NE(c.code, 0) << c.all();
    EXPECT_NE(c.code, 128 + 9) << "killed by the time limit: the FIFO was read\n" << c.all();
    expectOneError(c, {"ref/frame_0001.exr", "not a regular file"});
    expectInputsUntouched();
}

TEST_F(CliNothingLost, FifoAsFarmPlanIsRefused) {
    makeFifo(work() / "plan.json");
    auto r = box.runWithin(30, {"farm", "check", "--plan", "plan.json"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"--plan plan.json", "not a regular file"});
}

// --- GAMES202: every sibling file is an input -------------------------------------------

class CliNothingLostGames202 : public CliNothingLost {
protected:
    void SetUp() override {
        CliNothingLost::SetUp();
        if (IsSkipped()) return;
        // 32x24, frames 1-3 in G/: beauty_N.exr, normal_, position_, depth_, ID_, matrix_N.mat.
        auto r = box.run({"scenegen", "--layout", "games202", "--out", "G", "--width", "32",
                          "--height", "24", "--frames", "3", "--spp", "2"});
        ASSERT_EQ(r.code, 0) << r.all();
        ASSERT_TRUE(fs::exists(work() / "G" / "matrix_1.mat"));
        games = checksums(work() / "G");
    }
    CliResult runGames(const std::string& input, const std::string& output) {
        return box.run({"run",
                        (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "games202-jbf.json").string(),
                        "--input", input, "--output", output, "--frames", "1-3", "--threads", "2"});
    }
    std::map<std::string, uint64_t> games;
};

TEST_F(CliNothingLostGames202, OutputOverASiblingFileIsRefused) {
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"G", "G/beauty_%d.exr"},
        {"G", "G/normal_%d.exr"},
        {"G", "G/matrix_%d.mat"},
        {"G/beauty_%d.exr", "G/depth_%d.exr"},
        {"G/beauty_%d.exr", "G/../G/ID_%d.exr"},
    };
    for (const auto& [input, output] : cases) {
        SCOPED_TRACE(input + " -> " + output);
        auto r = runGames(input, output);
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {"frame 1", "input.path", "writing would destroy it"});
        EXPECT_EQ(checksums(work() / "G"), games) << "a GAMES202 input file changed";
    }
}

TEST_F(CliNothingLostGames202, FifoAsMatrixFileIsRefused) {
    fs::remove(work() / "G" / "matrix_2.mat");
    makeFifo(work() / "G" / "matrix_2.mat");
    auto r = box.runWithin(
        60, {"run", (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "games202-jbf.json").string(),
             "--input", "G", "--output", "out/g_%d.exr", "--frames", "1-3", "--threads", "2"});
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"G/matrix_2.mat", "not a regular file"});
}

// --- no command writes a file it reads -----------------------------------------------------

TEST_F(CliNothingLost, OneFrameOutputOverTheGraphOrAnIncludeIsRefused) {
    fs::copy_file(graphDir() / "copy.json", work() / "g.json");
    writeText(work() / "lib" / "empty.json", R"({"kestrel": 1, "groups": {}})");
    writeText(work() / "inc.json",
              R"({"kestrel": 1, "include": ["lib/empty.json"], "extends": "g.json"})");
    const auto graphs = checksums(work());
    for (const auto& [graph, output] : std::vector<std::pair<std::string, std::string>>{
             {"g.json", "g.json"}, {"inc.json", "lib/empty.json"}, {"inc.json", "./g.json"}}) {
        SCOPED_TRACE(graph + " -> " + output);
        auto r = box.run(runArgs(graph, {"--frames", "1", "--output", output}));
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {output, "writing would destroy it"});
        EXPECT_EQ(checksums(work()), graphs);
    }
}

TEST_F(CliNothingLost, GraphDotOverItsGraphOrAnInputFrameIsRefused) {
    fs::copy_file(graphDir() / "copy.json", work() / "g.json");
    const auto graphs = checksums(work());
    for (const std::string out : {"g.json", "scene/noisy/frame_0002.exr"}) {
        SCOPED_TRACE(out);
        auto r = box.run(
            {"graph", "g.json", "--input", "scene/noisy/frame_####.exr", "--dot", "-o", out});
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {"output " + out, "(-o)", "writing would destroy it"});
        EXPECT_EQ(checksums(work()), graphs);
    }
    auto ok = box.run({"graph", "g.json", "--dot", "-o", "g.dot"});
    EXPECT_EQ(ok.code, 0) << ok.all();
}

TEST_F(CliNothingLost, FarmPlanOverAnInputFrameIsRefused) {
    auto r = box.run({"farm", "plan", (graphDir() / "copy.json").string(), "--input",
                      "scene/noisy/frame_####.exr", "--output", "out/c.####.exr", "--frames", "1-3",
                      "--chunk", "2", "--out", "scene/noisy/frame_0001.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"scene/noisy/frame_0001.exr", "(--out)", "--input"});
    expectInputsUntouched();
}

TEST_F(CliNothingLost, ScenegenIntoARenderFolderNeedsForce) {
    auto r = box.run({"scenegen", "--out", "scene", "--width", "16", "--height", "12", "--frames",
                      "1", "--spp", "1", "--seed", "7"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"--out scene", "not empty", "--force"});
    expectInputsUntouched();
    auto forced = box.run({"scenegen", "--out", "scene", "--width", "16", "--height", "12",
                           "--frames", "1", "--spp", "1", "--seed", "7", "--force"});
    EXPECT_EQ(forced.code, 0) << forced.all();
}

// --- frames that are silently wrong ---------------------------------------------------------

/// Sets channel `name` of the EXR at `path` to `value` in the block [x0, x0+10) x [y0, y0+10),
/// every other channel and the header as they were.
void damageBlock(const fs::path& path, const std::string& name, float value, int x0, int y0) {
    Imf::Header header;
    std::map<std::string, std::vector<float>> planes;
    int w = 0, h = 0;
    {
        Imf::InputFile in(path.c_str());
        header = in.header();
        const Imath::Box2i dw = header.dataWindow();
        w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
        ASSERT_EQ(dw.min.x, 0);
        ASSERT_EQ(dw.min.y, 0);
        Imf::FrameBuffer fb;
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
            auto& p = planes[it.name()];
            p.assign(size_t(w) * size_t(h), 0.f);
            fb.insert(it.name(), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(p.data()),
                                            sizeof(float), sizeof(float) * size_t(w)));
        }
        in.setFrameBuffer(fb);
        in.readPixels(0, h - 1);
    }
    ASSERT_TRUE(planes.count(name)) << name;
    for (int y = y0; y < y0 + 10; ++y)
        for (int x = x0; x < x0 + 10; ++x) planes[name][size_t(y) * size_t(w) + size_t(x)] = value;
    Imf::FrameBuffer fb;
    for (auto& [n, p] : planes)
        fb.insert(n, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(p.data()), sizeof(float),
                                sizeof(float) * size_t(w)));
    Imf::OutputFile out(path.c_str(), header);
    out.setFrameBuffer(fb);
    out.writePixels(h);
}

/// The largest |value| of an EXR's R, G, B (infinity if any is NaN).
float largestMagnitude(const fs::path& path) {
    RgbImage img;
    std::string why;
    EXPECT_TRUE(readRgb(path.string(), img, &why)) << path << ": " << why;
    float m = 0;
    for (float v : img.rgb)
        m = std::isnan(v) ? std::numeric_limits<float>::infinity() : std::max(m, std::fabs(v));
    return m;
}

TEST_F(CliNothingLost, AbsurdInputValuesAreReplacedCountedAndNeverReachHistory) {
    const fs::path f2 = work() / "scene" / "noisy" / "frame_0002.exr";
    damageBlock(f2, "R", std::numeric_limits<float>::quiet_NaN(), 4, 4);
    damageBlock(f2, "G", -1e38f, 4, 4);
    damageBlock(f2, "B", std::numeric_limits<float>::infinity(), 4, 4);
    const float clean = largestMagnitude(work() / "scene" / "noisy" / "frame_0001.exr");
    auto r = box.run(runArgs((graphDir() / "taa.json").string(),
                             {"--frames", "1-3", "--output", "out/t.####.exr"}));
    EXPECT_EQ(r.code, 0) << r.all();
    EXPECT_FALSE(looksLikeCrash(r.all())) << r.all();
    // One warning for frame 2, counting each channel's 100 values.
    for (const char* needle : {"warning: frame 2: scene/noisy/frame_0002.exr: NaN, infinite",
                               "100 in color.R", "100 in color.G", "100 in color.B"})
        EXPECT_NE(r.err.find(needle), std::string::npos) << needle << "\n" << r.all();
    const auto first = r.err.find("NaN, infinite or absurd");
    EXPECT_EQ(r.err.find("NaN, infinite or absurd", first + 1), std::string::npos) << r.all();
    // The damage stays in its frame: frames 2 and 3 (whose history holds frame 2) are finite
    // and in the clean frames' range (TAA blends, it does not amplify).
    for (int f = 2; f <= 3; ++f)
        EXPECT_LE(largestMagnitude(work() / "out" / frameName("t.", f, ".exr")), 4 * clean + 1)
            << "frame " << f;
}

TEST_F(CliNothingLost, NegativeLightAndAlbedoAreReplacedEvenWithoutHistory) {
    // Issue 40, item 4: -1e10 colour on frame 1, where no history bounds it (it left -1e7 in
    // frame 12), and a negative albedo on frame 3 (a reflectance is never negative); svgf.json.
    ASSERT_TRUE(makeScene(box, work() / "long", 32, 24, 12));
    const fs::path noisy = work() / "long" / "noisy";
    for (const char* c : {"R", "G", "B"}) damageBlock(noisy / "frame_0001.exr", c, -1e10f, 4, 4);
    for (const char* c : {"albedo.R", "albedo.G", "albedo.B"})
        damageBlock(noisy / "frame_0003.exr", c, -0.5f, 20, 10);
    const float clean = largestMagnitude(noisy / "frame_0002.exr");
    auto r = box.run({"run", (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "svgf.json").string(),
                      "--input", "long/noisy/frame_####.exr", "--output", "out/s.####.exr"});
    EXPECT_EQ(r.code, 0) << r.all();
    for (const char* needle :
         {"warning: frame 1: long/noisy/frame_0001.exr: NaN, infinite", "100 in color.R",
          "warning: frame 3: long/noisy/frame_0003.exr", "100 in albedo.R"})
        EXPECT_NE(r.err.find(needle), std::string::npos) << needle << "\n" << r.all();
    for (int f = 1; f <= 12; ++f)
        EXPECT_LE(largestMagnitude(work() / "out" / frameName("s.", f, ".exr")), 4 * clean + 1)
            << "frame " << f;
}

TEST_F(CliNothingLost, GapInTheSequenceIsACutAndSaid) {
    auto gen = box.run({"scenegen", "--out", "gap", "--width", "32", "--height", "24", "--frames",
                        "4", "--spp", "2"});
    ASSERT_EQ(gen.code, 0) << gen.all();
    const fs::path third = work() / "gap" / "noisy" / "frame_0003.exr";
    auto runTaa = [&](const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> args = {"run",       (graphDir() / "taa.json").string(),
                                         "--input",   "gap/noisy/frame_####.exr",
                                         "--output",  out,
                                         "--threads", "2"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    };
    // Frame 4 after a cut: what a run starting at frame 4 computes (history empty).
    auto fresh = runTaa("fresh/t.####.exr", {"--frames", "4"});
    ASSERT_EQ(fresh.code, 0) << fresh.all();
    RgbImage expected;
    ASSERT_TRUE(readRgb((work() / "fresh" / "t.0004.exr").string(), expected));

    fs::remove(third);
    for (bool folder : {false, true}) {
        SCOPED_TRACE(folder ? "a folder named like frame 3" : "frame 3 missing");
        if (folder) fs::create_directory(third);
        const std::string dir = folder ? "b" : "a";
        auto r = runTaa(dir + "/t.####.exr", {});
        EXPECT_EQ(r.code, 0) << r.all();
        EXPECT_NE(r.err.find("warning: frames 2 and 4 of the input are not consecutive"),
                  std::string::npos)
            << r.all();
        EXPECT_NE(r.err.find("history reset at frame 4"), std::string::npos) << r.all();
        RgbImage got;
        ASSERT_TRUE(readRgb((work() / dir / "t.0004.exr").string(), got));
        EXPECT_EQ(got.rgb, expected.rgb) << "history was carried across the gap";
    }
}

// --- Mistakes refused before any work: farm plan, bench (item 13) ------------------------

TEST_F(CliNothingLost, FarmPlanOfAGraphThatCannotRunIsRefused) {
    writeText(work() / "bad.json", copyGraphWith(R"({"exposure": 500})"));
    struct Case {
        std::string graph, output;
        std::vector<std::string> needles;
    };
    const std::string copy = (graphDir() / "copy.json").string();
    for (const auto& c : std::vector<Case>{
             {"nosuch.json", "out/c.####.exr", {"nosuch.json"}},
             {"bad.json", "out/c.####.exr", {"passes[1].params.exposure", "got 500"}},
             {copy, "scene/noisy/frame_####.exr", {"is the input pattern", "--output"}}}) {
        SCOPED_TRACE(c.graph + " " + c.output);
        auto r =
            box.run({"farm", "plan", c.graph, "--input", "scene/noisy/frame_####.exr", "--output",
                     c.output, "--frames", "1-3", "--chunk", "2", "--out", "plan.sh"});
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {c.needles.front()});
        for (const auto& n : c.needles) EXPECT_NE(r.err.find(n), std::string::npos) << r.all();
        EXPECT_FALSE(fs::exists(work() / "plan.sh"));
    }
    expectInputsUntouched();
    // A plan made before the render exists still validates the graph alone.
    auto ok = box.run({"farm", "plan", copy, "--input", "later/f_####.exr", "--output",
                       "out/c.####.exr", "--frames", "1-3", "--chunk", "2", "--out", "plan.sh"});
    EXPECT_EQ(ok.code, 0) << ok.all();
}

TEST_F(CliNothingLost, BenchMistakesExitTwoWithTheReason) {
    const std::string copy = (graphDir() / "copy.json").string();
    // The split graph needs the diffuse/specular split this canonical scene lacks.
    const std::string split =
        (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "svgf-split.json").string();
    struct Case {
        std::vector<std::string> args;
        std::string needle;
    };
    for (const auto& c : std::vector<Case>{
             {{copy, "--input", "scene/noisy/frame_####.exr", "--frames", "1-x"}, "--frames"},
             {{copy, "--input", "scene/noisy/frame_####.exr", "--tonemap", "nosuch"}, "--tonemap"},
             {{copy, "--input", "nosuch/frame_####.exr"}, "nosuch/frame_####.exr"},
             {{split, "--input", "scene/noisy/frame_####.exr"}, "input.specular is absent"}}) {
        std::vector<std::string> args = {"bench"};
        args.insert(args.end(), c.args.begin(), c.args.end());
        args.insert(args.end(), {"--threads", "1"});
        SCOPED_TRACE(args[1] + " " + c.args.back());
        auto r = box.run(args);
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {c.needle});
        EXPECT_EQ(r.err.find("no graph could run"), std::string::npos) << r.all();
    }
    expectInputsUntouched();
}

// --- Output names checked before frame 1 (item 12) ---------------------------------------

TEST_F(CliNothingLost, FrameNumberInAFolderNameIsRefusedBeforeFrameOne) {
    for (const std::string out : {"out/####/c.exr", "out/shot_%04d/c.exr"}) {
        SCOPED_TRACE(out);
        auto r = box.run(
            runArgs((graphDir() / "copy.json").string(), {"--frames", "1-2", "--output", out}));
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {"'" + out + "'", "frame number in a folder name", "e.g. out/c."});
        EXPECT_FALSE(fs::exists(work() / "out")) << "written before the refusal";
    }
}

TEST_F(CliNothingLost, OutputNameTooLongForItsTemporaryIsRefusedBeforeFrameOne) {
    // NAME_MAX 255: ".NAME.tmp-PID" adds 6 bytes and a pid of up to 10 digits.
    const long nameMax = ::pathconf(work().c_str(), _PC_NAME_MAX);
    ASSERT_GT(nameMax, 20);
    auto named = [&](long bytes) {  // out/AAA...A.####.exr whose file names are `bytes` long
        return "out/" + std::string(size_t(bytes) - 9, 'a') + ".####.exr";
    };
    for (long bytes : {nameMax - 10, nameMax - 15}) {
        SCOPED_TRACE(bytes);
        auto r = box.run(runArgs((graphDir() / "copy.json").string(),
                                 {"--frames", "1-2", "--output", named(bytes)}));
        EXPECT_EQ(r.code, 2) << r.all();
        expectOneError(r, {"(output.path, frame 1)", std::to_string(bytes) + " bytes", "NAME_MAX",
                           "use at most " + std::to_string(nameMax - 16)});
        EXPECT_FALSE(fs::exists(work() / "out"));
    }
    auto ok = box.run(runArgs((graphDir() / "copy.json").string(),
                              {"--frames", "1-2", "--output", named(nameMax - 16)}));
    EXPECT_EQ(ok.code, 0) << ok.all();
    EXPECT_EQ(std::distance(fs::directory_iterator(work() / "out"), fs::directory_iterator()), 2);
}

TEST_F(CliNothingLost, ResumeWritesAgainAPreviewLostOrCutShort) {
    auto run = [&](std::vector<std::string> extra) {
        extra.insert(extra.begin(), {"--frames", "1-3", "--output", "out/c.####.exr", "--set",
                                     "output.preview=out/p.####.png"});
        return box.run(runArgs((graphDir() / "copy.json").string(), extra));
    };
    auto first = run({});
    ASSERT_EQ(first.code, 0) << first.all();
    const fs::path out = work() / "out";
    const std::string exr1 = readText(out / "c.0001.exr");
    struct Case {
        std::string damage, png;
    };
    for (const auto& c :
         std::vector<Case>{{"cut short", "p.0003.png"}, {"lost to a failed write", "p.0002.png"}}) {
        SCOPED_TRACE(c.damage);
        const std::string before = readText(out / c.png);
        if (c.damage == "cut short")
            writeText(out / c.png, before.substr(0, before.size() / 2));
        else
            fs::remove(out / c.png);
        auto resumed = run({"--resume"});
        EXPECT_EQ(resumed.code, 0) << resumed.all();
        EXPECT_NE(resumed.err.find("preview out/" + c.png + " is missing or incomplete"),
                  std::string::npos)
            << resumed.all();
        EXPECT_EQ(readText(out / c.png), before) << "the preview was not written again";
    }
    EXPECT_EQ(readText(out / "c.0001.exr"), exr1) << "--resume rewrote a complete frame";
}

// --- Outputs --resume and farm check trust (item 7) ---------------------------------------

/// Flips one bit of the byte `fromEnd` bytes before the end of `path`: inside the last chunk's
/// data (its zlib checksum at the very end), every chunk's size left as it was.
void flipBitNearEnd(const fs::path& path, size_t fromEnd) {
    std::string bytes = readText(path);
    ASSERT_GT(bytes.size(), fromEnd);
    bytes[bytes.size() - fromEnd] ^= 0x10;
    writeText(path, bytes);
}

/// Renames the header attribute `from` to `to` (as long) in place: a file written without it.
void renameAttribute(const fs::path& path, const std::string& from, const std::string& to) {
    std::string bytes = readText(path);
    const auto at = bytes.find(from + '\0');
    ASSERT_NE(at, std::string::npos) << from;
    bytes.replace(at, to.size(), to);
    writeText(path, bytes);
}

class CliResumeTrust : public CliNothingLost {
protected:
    CliResult run(std::vector<std::string> extra, const std::string& frames = "1-3") {
        extra.insert(extra.begin(), {"--frames", frames, "--output", "out/c.####.exr"});
        return box.run(runArgs((graphDir() / "copy.json").string(), extra));
    }
    fs::path out() const { return work() / "out"; }
};

TEST_F(CliResumeTrust, ResumeWritesAgainAFrameWithABitFlippedInsideAChunk) {
    ASSERT_EQ(run({}).code, 0);
    const std::string frame2 = readText(out() / "c.0002.exr");
    struct Case {
        std::string name;
        bool withChecksum;
        size_t fromEnd;  // the flipped byte
    };
    // With the checksum any byte is caught; without it (an older file) decoding must fail, so
    // the flip is in the zlib checksum that ends the last chunk.
    for (const auto& c : std::vector<Case>{{"checksum, chunk data", true, 9},
                                           {"checksum, zlib adler", true, 2},
                                           {"no checksum: decoded fully", false, 2}}) {
        SCOPED_TRACE(c.name);
        if (!c.withChecksum)
            renameAttribute(out() / "c.0002.exr", "kestrel.dataCrc32", "kestrel.dataCrcXX");
        flipBitNearEnd(out() / "c.0002.exr", c.fromEnd);
        auto resumed = run({"--resume"});
        EXPECT_EQ(resumed.code, 0) << resumed.all();
        EXPECT_NE(resumed.err.find("out/c.0002.exr is "), std::string::npos) << resumed.all();
        EXPECT_TRUE(readText(out() / "c.0002.exr") == frame2) << "the damaged frame was trusted";
    }
}

TEST_F(CliResumeTrust, ResumeRunsAgainFramesOfOtherParametersAndSaysWhich) {
    ASSERT_EQ(run({}, "1-2").code, 0);
    const std::string frame1 = readText(out() / "c.0001.exr");
    auto resumed = run({"--resume", "--set", "tonemap.exposure=1"});
    EXPECT_EQ(resumed.code, 0) << resumed.all();
    auto warnings = 0;
    std::istringstream err(resumed.err);
    for (std::string line; std::getline(err, line);)
        if (line.find("another graph or other parameters") != std::string::npos) {
            ++warnings;
            EXPECT_NE(line.find("out/c.0001.exr"), std::string::npos) << line;
            EXPECT_NE(line.find("frames from 1 on are run again"), std::string::npos) << line;
        }
    EXPECT_EQ(warnings, 1) << resumed.all();
    EXPECT_TRUE(readText(out() / "c.0001.exr") != frame1) << "a frame of other parameters was kept";
    EXPECT_TRUE(fs::exists(out() / "c.0003.exr"));
    // The same parameters again: every frame is this run's, nothing is rewritten.
    const std::string rewritten = readText(out() / "c.0001.exr");
    auto again = run({"--resume", "--set", "tonemap.exposure=1"});
    EXPECT_EQ(again.code, 0) << again.all();
    EXPECT_NE(again.err.find("every frame is already written"), std::string::npos) << again.all();
    EXPECT_TRUE(readText(out() / "c.0001.exr") == rewritten) << "a frame of this run was rewritten";
}

// --- Memory (item 10) ---------------------------------------------------------------------

/// Rewrites the data and display windows of the EXR at `path` to width x height, in place:
/// the header of a damaged or forged file, its pixels left as they are.
void forgeWindows(const fs::path& path, int32_t width, int32_t height) {
    std::string bytes = readText(path);
    for (const std::string name : {"dataWindow", "displayWindow"}) {
        const std::string key = name + '\0' + "box2i" + '\0';
        const auto at = bytes.find(key);
        ASSERT_NE(at, std::string::npos) << name;
        const int32_t box[4] = {0, 0, width - 1, height - 1};
        bytes.replace(at + key.size() + 4, sizeof box, reinterpret_cast<const char*>(box),
                      sizeof box);
    }
    writeText(path, bytes);
}

TEST_F(CliNothingLost, OutOfMemoryNamesTheFrameAndTheFileThatDeclaredItsSize) {
    // 3200x3200 with the scene's 25 float channels declares under 1 GiB (not refused by the
    // size rule); its planes do not fit in 150 MB of address space, the 32x24 frames do.
    fs::create_directories(work() / "forged");
    for (const char* f : {"frame_0001.exr", "frame_0002.exr"})
        fs::copy_file(work() / "scene" / "noisy" / f, work() / "forged" / f);
    forgeWindows(work() / "forged" / "frame_0002.exr", 3200, 3200);
    const std::vector<std::string> args = {"run",       (graphDir() / "copy.json").string(),
                                           "--input",   "forged/frame_####.exr",
                                           "--output",  "out/c.####.exr",
                                           "--threads", "2"};
    // Mid-sequence: not the first frame's size, refused before anything is allocated.
    auto r = box.runWithin(60, args, 150000);
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"frame 2", "forged/frame_0002.exr", "3200x3200", "32x24"});
    EXPECT_TRUE(fs::exists(work() / "out" / "c.0001.exr")) << "frame 1 fits: it is written";
    // As the first frame: its planes are allocated, and running out names the frame and file.
    auto first = args;
    first.insert(first.end(), {"--frames", "2"});
    auto oom = box.runWithin(60, first, 150000);
    EXPECT_EQ(oom.code, 1) << oom.all();
    expectOneError(oom,
                   {"frame 2: out of memory", "3200x3200 frame", "forged/frame_0002.exr declares"});
}

}  // namespace
