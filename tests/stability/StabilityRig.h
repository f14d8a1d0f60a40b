#pragma once
// Test rig of the stability suite (docs/design.md section 8): the real pass plugins loaded into a
// registry, a test-only source pass that emits hand-made (or scenegen-rendered) AOVs so extreme
// values can be injected at exact pixels, the shipped graphs rewired onto that source, and a
// runner that executes a graph frame after frame through kestrel::Executor.
#include <kestrel/Compiler.h>
#include <kestrel/Executor.h>
#include <kestrel/Graph.h>
#include <kestrel/Kestrel.h>

#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace stability {

/// One frame of source AOVs, by canonical port name (kestrel/Conventions.h). Ports the scenario
/// does not provide are absent for the whole run.
struct Frame {
    std::map<std::string, kestrel::Image, std::less<>> images;
    kestrel::SceneData scene;
    kestrel::Image& operator[](const std::string& port) { return images.at(port); }
};

/// Source content: the extent and a function filling frame `n` (images pre-allocated, zeroed,
/// for every provided port).
struct Scenario {
    kestrel::Extent extent{48, 32};
    std::set<std::string> provides{"color",  "albedo",   "normal",  "depth",
                                   "motion", "objectId", "position"};
    std::function<void(int64_t frame, Frame&)> fill;
};

/// Every port the test source can emit, with its format.
const std::vector<std::pair<std::string, kestrel::Format>>& sourcePorts();

/// Registry with every plugin of KESTREL_PLUGIN_BUILD_DIR plus the test source type
/// "StabilitySource" (param "scenario": a name given to setScenario). Loaded once per process.
kestrel::Registry& registry();
void setScenario(const std::string& name, Scenario scenario);

/// A graph ready to run on the test source, and the "pass.port" holding its final image.
struct TestGraph {
    kestrel::GraphDesc desc;
    std::string output;
};

/// A shipped graph (graphs/<file>) with its loader replaced by the test source running
/// `scenario` and its writers removed; the image the (first) writer received becomes the marked
/// output. Falls back to `fallbackJson` (same conventions, source named "input") when the file
/// does not exist yet; `usedShipped` tells which.
TestGraph shippedGraph(const std::string& file, const std::string& scenario,
                       bool* usedShipped = nullptr);
/// SVGF and GAMES202 JBF graphs on `scenario` (shipped when present, else composed here).
TestGraph svgfGraph(const std::string& scenario);
TestGraph jbfGraph(const std::string& scenario);
/// Sets `param` on every pass of `type` (e.g. all ATrous iterations). Returns how many.
int setParamOnType(TestGraph& g, const std::string& type, const std::string& param,
                   const std::string& jsonValue);

struct ImageStats {
    size_t nonFinite = 0;
    float min = 0, max = 0;  ///< over finite values
};
ImageStats stats(const kestrel::ImageView& v);
/// Planar copy of every channel.
std::vector<float> copyOf(const kestrel::ImageView& v);

struct RunOptions {
    int frames = 8;
    int64_t firstFrame = 1;
    int threads = 1;
    /// Called after each frame with the frame number and the marked output.
    std::function<void(int64_t, const kestrel::ImageView&)> onFrame;
    /// Frames before which Executor::resetHistory() is called (camera cut signalled by the app).
    std::set<int64_t> resetBefore;
};
/// Compiles and runs the graph; returns a copy of the last frame's output.
std::vector<float> run(const TestGraph& g, const RunOptions& options);

/// Deterministic hash noise in [0, 1) of (x, y, frame, salt).
float hashNoise(int x, int y, int64_t frame, uint32_t salt = 0);

/// A plausible diffuse scene: noisy radiance around a smooth gradient (values in [0.2, 1.55)),
/// albedo 0.5, a tilted plane (depth 5 + 0.02 x + 0.01 y, matching positions), normal (0, 0, 1),
/// object 0, no motion. `modify` may then inject extreme values.
Scenario plainScene(kestrel::Extent extent, std::function<void(int64_t, Frame&)> modify = nullptr);

}  // namespace stability

namespace kestrel::scenegen {
struct SceneOptions;
}

namespace stability {

/// The scenegen path tracer as a source: every AOV and the camera/object matrices of each frame,
/// rendered in memory (no EXR round trip).
Scenario sceneGenScenario(const kestrel::scenegen::SceneOptions& options);
/// docs/design.md section 7: mean((x - r)^2 / (r^2 + 1e-2)) over planar RGB.
double relMse(const std::vector<float>& out, const std::vector<float>& ref);

}  // namespace stability
