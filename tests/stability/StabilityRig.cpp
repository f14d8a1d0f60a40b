#include "StabilityRig.h"

#include <kestrel/Plugin.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>

namespace stability {

using namespace kestrel;
namespace fs = std::filesystem;

namespace {

std::map<std::string, Scenario>& scenarios() {
    static std::map<std::string, Scenario> s;
    return s;
}

/// Test-only source: emits the AOVs of a Scenario. It caches the current frame's images (the
/// frame being produced, not temporal state).
class StabilitySource final : public Pass {
public:
    static PassDesc describe() {
        PassDesc d("StabilitySource", "test source emitting hand-made AOVs (stability suite)");
        for (const auto& [name, format] : sourcePorts()) d.output(name, format, name);
        d.paramString("scenario", "", "name given to stability::setScenario");
        return d;
    }
    explicit StabilitySource(const ParamValues& p) {
        auto it = scenarios().find(p.getString("scenario"));
        if (it == scenarios().end())
            throw Error("StabilitySource: unknown scenario '" + p.getString("scenario") + "'");
        scenario_ = &it->second;
    }
    void resolve(ResolveContext& rc) override {
        for (const auto& [name, format] : sourcePorts())
            if (!scenario_->provides.count(name)) rc.setAbsent(name, "scenario lacks it");
        // As the ExrLoader: a render offering jittered albedos is an anti-aliased one.
        rc.setFact("antiAliased", scenario_->provides.count("jitteredAlbedo") ? "true" : "false");
    }
    std::optional<Extent> beginFrame(FrameContext& ctx) override {
        frame_.images.clear();
        frame_.scene = SceneData{};
        for (const auto& [name, format] : sourcePorts())
            if (scenario_->provides.count(name))
                frame_.images.emplace(name, Image(scenario_->extent, format));
        if (scenario_->fill) scenario_->fill(ctx.frameNumber, frame_);
        if (ctx.scene) *ctx.scene = frame_.scene;
        return scenario_->extent;
    }
    void execute(FrameContext&, PassIO& io) override {
        for (const auto& [name, img] : frame_.images) {
            if (!io.hasOutput(name)) continue;
            const ImageView& o = io.output(name);
            for (int c = 0; c < img.view().channels(); ++c)
                std::copy(img.channel(c), img.channel(c) + img.view().pixels(), o.channel(c));
        }
    }

private:
    const Scenario* scenario_ = nullptr;
    Frame frame_;
};

struct Loaded {
    PluginLoader loader;  // declared first: outlives every pass created from its types
    Registry registry;
};

std::string readGraphOutputFromSinks(GraphDesc& g, const Registry& r) {
    std::set<std::string> sinks;
    for (const auto& p : g.passes) {
        const PassType* t = r.find(p.type);
        if (t && t->desc.sink) sinks.insert(p.name);
    }
    std::string output;
    std::vector<EdgeDesc> kept;
    for (const auto& e : g.edges) {
        if (sinks.count(e.toPass)) {
            if (output.empty() && e.toPort == "color") output = e.fromPass + "." + e.fromPort;
            continue;
        }
        kept.push_back(e);
    }
    g.edges = std::move(kept);
    std::erase_if(g.passes, [&](const PassNode& p) { return sinks.count(p.name) > 0; });
    std::erase_if(g.outputs,
                  [&](const std::string& o) { return sinks.count(o.substr(0, o.find('.'))) > 0; });
    return output;
}

// SVGF as the paper describes it (Schied et al. 2017), used until graphs/svgf.json lands:
// demodulate, reprojection (motion), temporal accumulation, 5 A-Trous iterations (feedback of the
// first), modulate.
const char* kSvgfFallback = R"({"kestrel": 1, "name": "svgf-stability",
  "passes": [
    {"name": "input", "type": "ExrLoader"},
    {"name": "demod", "type": "Demodulate"},
    {"name": "reproj", "type": "Reprojection"},
    {"name": "temporal", "type": "TemporalAccumulation"},
    {"name": "atrous0", "type": "ATrous", "params": {"step": 1}},
    {"name": "atrous1", "type": "ATrous", "params": {"step": 2}},
    {"name": "atrous2", "type": "ATrous", "params": {"step": 4}},
    {"name": "atrous3", "type": "ATrous", "params": {"step": 8}},
    {"name": "atrous4", "type": "ATrous", "params": {"step": 16}},
    {"name": "modulate", "type": "Modulate"},
    {"name": "output", "type": "ExrWriter"}],
  "edges": [
    {"from": "input.color", "to": "demod.color"},
    {"from": "input.albedo", "to": "demod.albedo"},
    {"from": "input.emission", "to": "demod.emission"},
    {"from": "input.depth", "to": "reproj.depth"},
    {"from": "input.normal", "to": "reproj.normal"},
    {"from": "input.objectId", "to": "reproj.objectId"},
    {"from": "input.motion", "to": "reproj.motion"},
    {"from": "input.position", "to": "reproj.position"},
    {"from": "input.depth", "to": "reproj.prevDepth", "history": true},
    {"from": "input.normal", "to": "reproj.prevNormal", "history": true},
    {"from": "input.objectId", "to": "reproj.prevObjectId", "history": true},
    {"from": "atrous0.color", "to": "reproj.prevColor", "history": true},
    {"from": "temporal.moments", "to": "reproj.prevMoments", "history": true},
    {"from": "temporal.historyLength", "to": "reproj.prevHistoryLength", "history": true},
    {"from": "demod.illumination", "to": "temporal.color"},
    {"from": "reproj.color", "to": "temporal.prevColor"},
    {"from": "reproj.moments", "to": "temporal.prevMoments"},
    {"from": "reproj.historyLength", "to": "temporal.prevHistoryLength"},
    {"from": "temporal.color", "to": "atrous0.color"},
    {"from": "temporal.variance", "to": "atrous0.variance"},
    {"from": "atrous0.color", "to": "atrous1.color"},
    {"from": "atrous0.variance", "to": "atrous1.variance"},
    {"from": "atrous1.color", "to": "atrous2.color"},
    {"from": "atrous1.variance", "to": "atrous2.variance"},
    {"from": "atrous2.color", "to": "atrous3.color"},
    {"from": "atrous2.variance", "to": "atrous3.variance"},
    {"from": "atrous3.color", "to": "atrous4.color"},
    {"from": "atrous3.variance", "to": "atrous4.variance"},
    {"from": "input.depth", "to": "atrous0.depth"}, {"from": "input.normal", "to": "atrous0.normal"},
    {"from": "input.objectId", "to": "atrous0.objectId"},
    {"from": "input.depth", "to": "atrous1.depth"}, {"from": "input.normal", "to": "atrous1.normal"},
    {"from": "input.objectId", "to": "atrous1.objectId"},
    {"from": "input.depth", "to": "atrous2.depth"}, {"from": "input.normal", "to": "atrous2.normal"},
    {"from": "input.objectId", "to": "atrous2.objectId"},
    {"from": "input.depth", "to": "atrous3.depth"}, {"from": "input.normal", "to": "atrous3.normal"},
    {"from": "input.objectId", "to": "atrous3.objectId"},
    {"from": "input.depth", "to": "atrous4.depth"}, {"from": "input.normal", "to": "atrous4.normal"},
    {"from": "input.objectId", "to": "atrous4.objectId"},
    {"from": "atrous4.color", "to": "modulate.illumination"},
    {"from": "input.albedo", "to": "modulate.albedo"},
    {"from": "input.emission", "to": "modulate.emission"},
    {"from": "modulate.color", "to": "output.color"}],
  "outputs": []})";

// GAMES202 pipeline (homework 5), used until graphs/games202-jbf.json lands.
const char* kJbfFallback = R"({"kestrel": 1, "name": "jbf-stability",
  "passes": [
    {"name": "input", "type": "ExrLoader"},
    {"name": "jbf", "type": "JointBilateral", "params": {"radius": 4, "sigmaCoord": 2.0}},
    {"name": "reproj", "type": "Reprojection"},
    {"name": "accum", "type": "ClampedAccumulation"},
    {"name": "output", "type": "ExrWriter"}],
  "edges": [
    {"from": "input.color", "to": "jbf.color"},
    {"from": "input.normal", "to": "jbf.normal"},
    {"from": "input.position", "to": "jbf.position"},
    {"from": "input.depth", "to": "jbf.depth"},
    {"from": "input.objectId", "to": "jbf.objectId"},
    {"from": "input.depth", "to": "reproj.depth"},
    {"from": "input.normal", "to": "reproj.normal"},
    {"from": "input.objectId", "to": "reproj.objectId"},
    {"from": "input.motion", "to": "reproj.motion"},
    {"from": "input.position", "to": "reproj.position"},
    {"from": "input.depth", "to": "reproj.prevDepth", "history": true},
    {"from": "input.normal", "to": "reproj.prevNormal", "history": true},
    {"from": "input.objectId", "to": "reproj.prevObjectId", "history": true},
    {"from": "accum.color", "to": "reproj.prevColor", "history": true},
    {"from": "jbf.color", "to": "accum.color"},
    {"from": "reproj.color", "to": "accum.history"},
    {"from": "reproj.historyLength", "to": "accum.historyLength"},
    {"from": "accum.color", "to": "output.color"}],
  "outputs": []})";

}  // namespace

const std::vector<std::pair<std::string, Format>>& sourcePorts() {
    static const std::vector<std::pair<std::string, Format>> ports = {
        {"color", Format::Float3},
        {"albedo", Format::Float3},
        {"emission", Format::Float3},
        {"direct", Format::Float3},
        {"indirect", Format::Float3},
        {"diffuse", Format::Float3},
        {"specular", Format::Float3},
        {"diffuseAlbedo", Format::Float3},
        {"specularAlbedo", Format::Float3},
        {"normal", Format::Float3},
        {"depth", Format::Float},
        {"position", Format::Float3},
        {"motion", Format::Float2},
        {"objectId", Format::Int32},
        {"jitteredAlbedo", Format::Float3},
        {"jitteredDiffuseAlbedo", Format::Float3},
        {"jitteredSpecularAlbedo", Format::Float3},
        // As the ExrLoader's optional outputs graphs/svgf.json reads (VirtualMotion): absent
        // unless a scenario provides them.
        {"reflection", Format::Float},
        {"pathLength", Format::Float},
        {"lightThroughMirror", Format::Float}};
    return ports;
}

Registry& registry() {
    static std::unique_ptr<Loaded> loaded = [] {
        auto l = std::make_unique<Loaded>();
        l->loader.loadDirectories({KESTREL_PLUGIN_BUILD_DIR}, l->registry);
        l->registry.add<StabilitySource>();
        return l;
    }();
    return loaded->registry;
}

void setScenario(const std::string& name, Scenario scenario) {
    scenarios()[name] = std::move(scenario);
}

TestGraph shippedGraph(const std::string& file, const std::string& fallbackJson,
                       const std::string& scenario, bool* usedShipped) {
    const fs::path path = fs::path(KESTREL_SOURCE_DIR) / "graphs" / file;
    const bool shipped = fs::exists(path);
    if (usedShipped) *usedShipped = shipped;
    TestGraph g;
    g.desc = shipped ? loadGraphFile(path) : parseGraph(fallbackJson);
    const std::string params = "{\"scenario\": \"" + scenario + "\"}";
    for (auto& p : g.desc.passes)
        if (p.type == "ExrLoader") {
            p.type = "StabilitySource";
            p.paramsJson = params;
        }
    g.output = readGraphOutputFromSinks(g.desc, registry());
    if (g.output.empty() && !g.desc.outputs.empty()) g.output = g.desc.outputs.front();
    if (g.output.empty()) throw std::runtime_error(file + ": no writer and no output to read");
    g.desc.outputs.push_back(g.output);
    return g;
}

TestGraph shippedGraph(const std::string& file, const std::string& scenario, bool* usedShipped) {
    const std::string fallback = file == "svgf.json" ? kSvgfFallback : kJbfFallback;
    return shippedGraph(file, fallback, scenario, usedShipped);
}

TestGraph svgfGraph(const std::string& scenario) {
    return shippedGraph("svgf.json", kSvgfFallback, scenario, nullptr);
}
TestGraph jbfGraph(const std::string& scenario) {
    return shippedGraph("games202-jbf.json", kJbfFallback, scenario, nullptr);
}

int setParamOnType(TestGraph& g, const std::string& type, const std::string& param,
                   const std::string& jsonValue) {
    int n = 0;
    for (const auto& p : g.desc.passes)
        if (p.type == type) {
            applyOverride(g.desc, p.name + "." + param + "=" + jsonValue);
            ++n;
        }
    return n;
}

ImageStats stats(const ImageView& v) {
    ImageStats s;
    s.min = std::numeric_limits<float>::max();
    s.max = -std::numeric_limits<float>::max();
    for (int c = 0; c < v.channels(); ++c)
        for (size_t i = 0; i < v.pixels(); ++i) {
            const float x = v.channel(c)[i];
            if (!std::isfinite(x)) {
                ++s.nonFinite;
                continue;
            }
            s.min = std::min(s.min, x);
            s.max = std::max(s.max, x);
        }
    return s;
}

std::vector<float> copyOf(const ImageView& v) {
    std::vector<float> out;
    out.reserve(v.pixels() * size_t(v.channels()));
    for (int c = 0; c < v.channels(); ++c)
        out.insert(out.end(), v.channel(c), v.channel(c) + v.pixels());
    return out;
}

std::vector<float> run(const TestGraph& g, const RunOptions& o) {
    auto compiled = compileGraph(g.desc, registry(), CompileOptions{o.firstFrame, false});
    Parallel parallel(o.threads);
    Executor ex(*compiled, parallel);
    const int64_t last = o.firstFrame + o.frames - 1;
    ex.beginRun(o.firstFrame, last);
    std::vector<float> result;
    for (int64_t f = o.firstFrame; f <= last; ++f) {
        if (o.resetBefore.count(f)) ex.resetHistory();
        ex.runFrame(f);
        const ImageView out = ex.output(g.output);
        if (o.onFrame) o.onFrame(f, out);
        if (f == last) result = copyOf(out);
    }
    ex.endRun();
    return result;
}

float hashNoise(int x, int y, int64_t frame, uint32_t salt) {
    // PCG-style integer hash (O'Neill 2014 output permutation) of the packed coordinates.
    uint32_t h = uint32_t(x) * 0x8da6b343u ^ uint32_t(y) * 0xd8163841u ^
                 uint32_t(frame) * 0xcb1ab31fu ^ salt * 0x9e3779b9u;
    h = h * 747796405u + 2891336453u;
    h = ((h >> ((h >> 28u) + 4u)) ^ h) * 277803737u;
    h = (h >> 22u) ^ h;
    return float(h >> 8) * (1.f / 16777216.f);
}

Scenario plainScene(Extent extent, std::function<void(int64_t, Frame&)> modify) {
    Scenario s;
    s.extent = extent;
    s.fill = [extent, modify](int64_t frame, Frame& f) {
        const int w = extent.width, h = extent.height;
        // Looked up once per frame: per pixel, the map lookups were most of a run under ASan.
        kestrel::Image &color = f["color"], &albedo = f["albedo"], &normal = f["normal"];
        kestrel::Image &depth = f["depth"], &position = f["position"], &id = f["objectId"];
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const float base = 0.3f + 0.4f * float(x) / float(std::max(1, w - 1));
                for (int c = 0; c < 3; ++c)
                    color.at(c, x, y) =
                        0.05f + base * (0.5f + hashNoise(x, y, frame, uint32_t(c)) * 1.5f);
                for (int c = 0; c < 3; ++c) albedo.at(c, x, y) = 0.5f;
                normal.at(2, x, y) = 1.f;
                const float z = 5.f + 0.02f * float(x) + 0.01f * float(y);
                depth.at(0, x, y) = z;
                position.at(0, x, y) = 0.01f * float(x);
                position.at(1, x, y) = -0.01f * float(y);
                position.at(2, x, y) = -z;
                id.atInt(x, y) = 0;
            }
        if (modify) modify(frame, f);
    };
    return s;
}

}  // namespace stability
