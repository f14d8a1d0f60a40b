// Per-region quality of every shipped SVGF graph on every zoo scene (kestrel scenegen --scene) and
// every public Blender sequence in ../shared/data. A filter can improve the frame on average and
// still ruin a region: a black sky, an emitter subtracted twice, a smeared mirror. So each region
// of eval/Regions.h (background, emissive, glossy, textured, disoccluded, from the input's
// G-buffer) must come out no worse than the 1-spp input it was made from, and the whole frame
// must gain clearly. One test per graph x scene (ctest -R Quality runs them in parallel); a
// failure names graph, scene and region with both numbers.
//
// Outputs are taken in-process as float32 (the writer replaced by a marked output), so a noise-free
// sky that passes through unchanged is compared exactly, not through half-float quantisation.
#include <eval/ExrRgb.h>
#include <eval/Metrics.h>
#include <eval/Regions.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <kestrel/Compiler.h>
#include <kestrel/Executor.h>
#include <kestrel/FramePattern.h>
#include <kestrel/Plugin.h>
#include <scenegen/SceneGen.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "../GraphTestUtil.h"

namespace fs = std::filesystem;
using namespace kestrel;

namespace {

// A region where the input is already exact (noise-free sky, emitter) must come out unchanged:
// output MSE may exceed the input's by at most eval::RegionStats::kMseSlack (1e-6, PSNR 60 dB)
// on tone-mapped display values in [0, 1] (eval::ToneMap::Reinhard), the slack kestrel compare
// reports regions with: invisible, yet far below any real regression (re-adding the emission
// subtraction to the specular chain turns the street's sky black: MSE 0.44 there). Measured at
// 72fc987: unchanged skies within 6e-10 (92 dB).
constexpr double kMseSlack = eval::RegionStats::kMseSlack;
// The whole frame (all pixels of frames 1-12) must gain at least this much PSNR over the input.
// Measured at 72fc987: 6.6-7.3 dB on the zoo streets, 12-13 dB on the rooms, 12-20 dB on the
// Blender sequences, 1.2 dB on fireflies. A black sky drops the street 8 dB below its input.
constexpr double kMinGainDb = 3.0;
// fireflies: the lamp's light reaches the 1-spp frames only as rare samples thousands of times
// too bright. TemporalAccumulation clamps them before they enter the history; where the clamp
// would take off a large share of the light around them, the svgf chains spread that energy over
// the same surface instead of dropping it (fireflySpread): 3.1 dB gained on display values where
// dropping it gained 1.3 (the lit ground stayed dark). Its bar is 2.5 dB; every region must
// still improve.
// The GAMES202 graphs are single-frame colour filters with clamped accumulation: measured gains
// of 2.7 (atrous on the zoo street) to 16 dB; their bar is 1 dB, which a black sky still fails.
bool isGames202(const std::string& graph) {
    return graph.rfind("games202-", 0) == 0;
}
double minGainDb(const std::string& graph, const std::string& scene) {
    if (isGames202(graph)) return 1.0;
    return scene == "fireflies" ? 2.5 : kMinGainDb;
}

constexpr int64_t kFirstFrame = 1, kLastFrame = 12;

struct Scene {
    std::string name;
    bool split = false;   ///< has the diffuse/specular split: svgf-split.json applies
    bool shared = false;  ///< a public sequence in ../shared/data, else a generated zoo scene
};

std::vector<Scene> allScenes() {
    std::vector<Scene> scenes;
    // scenegen writes the split for the street kinds, never for the room.
    for (const auto& z : scenegen::zooScenes())
        scenes.push_back({z.name, z.options.kind != scenegen::SceneOptions::Kind::Room, false});
    scenes.push_back({"blender-sample-room", true, true});
    scenes.push_back({"blender-street", true, true});
    scenes.push_back({"blender-showroom", true, true});
    // Blender's default passes: no DiffCol/GlossCol, so no split.
    scenes.push_back({"blender-street-defaults", false, true});
    return scenes;
}

struct Case {
    std::string graph;
    Scene scene;
};

std::vector<Case> allCases() {
    std::vector<Case> cases;
    for (const char* graph : {"svgf.json", "svgf-notaa.json", "svgf-fast.json", "svgf-split.json",
                              "games202-jbf.json", "games202-atrous.json"})
        for (const Scene& s : allScenes())
            if (std::string(graph) != "svgf-split.json" || s.split) cases.push_back({graph, s});
    return cases;
}

// gtest prints parameters in failure lines and ctest test names.
void PrintTo(const Case& c, std::ostream* os) {
    *os << c.graph << " on " << c.scene.name;
}

/// The shipped graph, or its namesake in $KESTREL_QUALITY_GRAPHS: a candidate graph (or a
/// deliberately broken one) is checked without touching graphs/.
fs::path graphPath(const std::string& graph) {
    const char* dir = std::getenv("KESTREL_QUALITY_GRAPHS");
    return fs::path(dir && *dir ? dir : KESTREL_SOURCE_DIR "/graphs") / graph;
}

std::string caseName(const testing::TestParamInfo<Case>& info) {
    std::string n =
        info.param.graph.substr(0, info.param.graph.find('.')) + "_" + info.param.scene.name;
    std::replace(n.begin(), n.end(), '-', '_');
    return n;
}

/// Where generated zoo scenes live: shared by the test processes of one build of this binary
/// (ctest runs each test in its own process; a scene takes seconds to render and several graphs
/// read it). Keyed by the binary's modification time, so a rebuilt scene generator re-renders.
fs::path zooCacheRoot() {
    const auto stamp = fs::last_write_time("/proc/self/exe").time_since_epoch().count();
    return fs::path(KESTREL_BINARY_DIR) / "tests" / "quality" /
           ("zoo-" + std::to_string(static_cast<unsigned long long>(stamp)));
}

/// Scenes rendered by earlier builds of this binary are never read again.
void removeStaleCaches() {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(zooCacheRoot().parent_path(), ec))
        if (e.path().filename().string().starts_with("zoo-") && e.path() != zooCacheRoot())
            fs::remove_all(e.path(), ec);
}

/// Holds an exclusive lock on a file while alive: a test that needs a scene another process is
/// rendering waits for it instead of rendering it a second time.
class FileLock {
public:
    explicit FileLock(const fs::path& path) : fd_(::open(path.c_str(), O_CREAT | O_RDWR, 0644)) {
        if (fd_ < 0 || ::flock(fd_, LOCK_EX) != 0)
            throw std::runtime_error("cannot lock " + path.string());
    }
    ~FileLock() { ::close(fd_); }
    FileLock(const FileLock&) = delete;
    FileLock& operator=(const FileLock&) = delete;

private:
    int fd_;
};

/// Renders zoo scene `name` once per build; "done" marks a complete scene (a process killed while
/// rendering leaves none, and the next one starts over).
fs::path zooScene(const std::string& name) {
    const fs::path root = zooCacheRoot(), dir = root / name;
    fs::create_directories(root);
    FileLock lock(root / (name + ".lock"));
    if (fs::exists(dir / "done")) return dir;
    removeStaleCaches();
    fs::remove_all(dir);
    fs::create_directories(dir);
    scenegen::writeSequence(scenegen::zooScene(name).options, dir);
    std::ofstream(dir / "done") << "1\n";
    return dir;
}

/// Runs `graph` over the scene (its writer replaced by a marked output, float32) and sums the
/// error per region for the output and for the 1-spp input.
eval::RegionStats measure(const fs::path& graph, const fs::path& scene) {
    const std::string input = (scene / "noisy/frame_####.exr").string(),
                      ref = (scene / "ref/frame_####.exr").string();
    GraphDesc g = loadGraphFile(graph);
    applyOverride(g, "input.path=" + nlohmann::json(input).dump());
    const std::string marked = testutil::markWriterInput(g);
    CompileOptions copt;
    copt.firstFrame = kFirstFrame;
    auto compiled = compileGraph(g, testutil::builtPlugins(), copt);
    Parallel parallel(1);  // ctest runs two tests at once on the 2-core machine
    Executor exec(*compiled, parallel);
    exec.beginRun(kFirstFrame, kLastFrame);
    eval::GBufferReader gbuffers(testutil::builtPlugins(), input, kFirstFrame);
    eval::RegionStats stats;
    eval::GBuffer prev;
    for (int64_t f = kFirstFrame; f <= kLastFrame; ++f) {
        exec.runFrame(f, false);
        eval::GBuffer cur = gbuffers.read(f);
        const eval::RegionMasks masks =
            eval::classifyRegions(cur, f == kFirstFrame ? nullptr : &prev);
        const Image reference = eval::readExrRgb(expandFramePattern(ref, f));
        stats.add(exec.output(marked), reference.view(), cur.color.view(), masks);
        prev = std::move(cur);
    }
    exec.endRun();
    return stats;
}

double outMse(const eval::RegionStats& s, int k) {
    return s.outSse[size_t(k)] / double(s.samples[size_t(k)]);
}
double inMse(const eval::RegionStats& s, int k) {
    return s.inSse[size_t(k)] / double(s.samples[size_t(k)]);
}

std::string format(const char* f, auto... args) {
    char buf[256];
    std::snprintf(buf, sizeof buf, f, args...);
    return buf;
}

// The GAMES202 graphs filter the colour itself, without demodulation or the diffuse/specular
// split (the homework's algorithm): a mirror's sharp reflection is blurred like noise. Measured:
// the zoo street's glossy region 19.60 -> 18.24 dB (jbf), 16.98 (atrous); the zoo street-static's
// 19.95 -> 19.86, 17.33. That region is reported, not asserted, for them; every other region is.
bool asserted(const std::string& graph, int region) {
    return !(isGames202(graph) && (region == eval::kGlossy || region == eval::kReflection));
}

void expectNoRegionWorse(const std::string& graph, const std::string& what,
                         const eval::RegionStats& s) {
    for (int k = eval::kBackground; k < eval::kRegionCount; ++k) {
        if (!s.has(k) || !asserted(graph, k)) continue;
        EXPECT_FALSE(s.worseThanInput(k))
            << what << ", region " << eval::regionName(k)
            << format(
                   ": output MSE %.4g (%.2f dB) worse than the 1-spp input's %.4g (%.2f dB) "
                   "beyond the slack %.0e",
                   outMse(s, k), s.outPsnr(k), inMse(s, k), s.inPsnr(k), kMseSlack);
    }
}

void expectFrameGain(const std::string& what, const eval::RegionStats& s, double minGain) {
    const double out = s.outPsnr(eval::kAll), in = s.inPsnr(eval::kAll);
    EXPECT_GT(out, in + minGain)
        << what
        << format(
               ", whole frame: output PSNR %.2f dB, 1-spp input %.2f dB: gain %.2f dB, "
               "expected more than %.1f dB",
               out, in, out - in, minGain);
}

// Speckles (Metrics.h: isolated dark pixels) svgf.json may leave on the zoo rooms, per megapixel
// per frame over frames 1-12: a black 1-spp sample with no history, on a curved surface at 96x64,
// stayed black among filled neighbours (949 on the room before HistoryFix; 122 after, 109 on
// room-cut, 136 on room-lamp). Most of those frames' speckles are on frames 1 and 2.
constexpr double kMaxRoomSpeckles = 300;

void expectFewSpeckles(const Case& c, const eval::RegionStats& s) {
    if (c.graph != "svgf.json" || c.scene.name.rfind("room", 0) != 0) return;
    EXPECT_LE(s.speckles(eval::kAll), kMaxRoomSpeckles)
        << c.graph << " on " << c.scene.name << ": speckles per megapixel";
}

class QualityRegions : public testing::TestWithParam<Case> {};

TEST_P(QualityRegions, NoRegionWorseThanInputAndFrameGains) {
    const Case& c = GetParam();
    fs::path scene;
    if (c.scene.shared) {
        scene = fs::path(KESTREL_SHARED_DIR) / "data" / c.scene.name;
        if (!fs::exists(scene / "noisy" / "frame_0001.exr"))
            GTEST_SKIP() << "../shared/data/" << c.scene.name << " not present (a user's clone)";
    } else {
        scene = zooScene(c.scene.name);
    }
    const auto t0 = std::chrono::steady_clock::now();
    const eval::RegionStats s = measure(graphPath(c.graph), scene);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%s on %s (frames %lld-%lld, %.1f s):\n%s", graphPath(c.graph).c_str(),
                c.scene.name.c_str(), (long long)kFirstFrame, (long long)kLastFrame, seconds,
                eval::formatRegionTable(s).c_str());
    const std::string what = c.graph + " on " + c.scene.name;
    expectNoRegionWorse(c.graph, what, s);
    expectFrameGain(what, s, minGainDb(c.graph, c.scene.name));
    expectFewSpeckles(c, s);
}

INSTANTIATE_TEST_SUITE_P(Quality, QualityRegions, testing::ValuesIn(allCases()), caseName);

// TAA must earn its place where it runs (anti-aliased renders): on Blender's usual
// denoising set-up (1.5 px pixel filter, jittered G-buffer, anti-aliased reference) svgf.json
// beats svgf-notaa.json. Its history reprojection runs without the depth/normal tests, which
// on a jittered G-buffer rejected the edges TAA anti-aliases (measured frames 5-12: 30.20 dB
// with them, 30.71 without, svgf-notaa.json 30.24).
TEST(QualityTaa, BeatsNoTaaOnAnAntiAliasedBlenderRender) {
    const fs::path scene = fs::path(KESTREL_SHARED_DIR) / "data" / "blender-street-defaults";
    if (!fs::exists(scene / "noisy" / "frame_0001.exr"))
        GTEST_SKIP() << "../shared/data/blender-street-defaults not present (a user's clone)";
    const double taa = measure(graphPath("svgf.json"), scene).outPsnr(eval::kAll);
    const double noTaa = measure(graphPath("svgf-notaa.json"), scene).outPsnr(eval::kAll);
    std::printf(
        "blender-street-defaults, frames %lld-%lld: svgf.json %.2f dB, svgf-notaa.json "
        "%.2f dB\n",
        (long long)kFirstFrame, (long long)kLastFrame, taa, noTaa);
    EXPECT_GT(taa, noTaa + 0.1) << "TAA costs PSNR on an anti-aliased render";
}

}  // namespace
