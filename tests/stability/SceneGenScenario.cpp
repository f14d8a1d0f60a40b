#include <scenegen/SceneGen.h>

#include "StabilityRig.h"

namespace stability {

using namespace kestrel;

namespace {
template <size_t N>
void copyPlanes(const std::array<std::vector<float>, N>& src, Image& dst) {
    for (size_t c = 0; c < N; ++c) std::copy(src[c].begin(), src[c].end(), dst.channel(int(c)));
}
}  // namespace

Scenario sceneGenScenario(const scenegen::SceneOptions& options) {
    Scenario s;
    s.extent = {options.width, options.height};
    s.provides = {"color", "albedo", "emission", "normal",
                  "depth", "motion", "objectId", "position"};
    s.fill = [options](int64_t frame, Frame& f) {
        const scenegen::FrameAovs a = scenegen::renderFrame(options, int(frame));
        copyPlanes(a.color, f["color"]);
        copyPlanes(a.albedo, f["albedo"]);
        copyPlanes(a.emission, f["emission"]);
        copyPlanes(a.normal, f["normal"]);
        copyPlanes(a.position, f["position"]);
        copyPlanes(a.motion, f["motion"]);
        std::copy(a.depth.begin(), a.depth.end(), f["depth"].channel(0));
        std::copy(a.objectId.begin(), a.objectId.end(), f["objectId"].view().ints());
        f.scene.hasCamera = true;
        f.scene.worldToCamera = a.worldToCamera;
        f.scene.worldToPixel = a.worldToPixel;
        for (const auto& [id, m] : a.objectToWorld) f.scene.objectToWorld[id] = m;
    };
    return s;
}

double relMse(const std::vector<float>& out, const std::vector<float>& ref) {
    double sum = 0;
    for (size_t i = 0; i < out.size(); ++i) {
        const double d = double(out[i]) - double(ref[i]);
        sum += d * d / (double(ref[i]) * double(ref[i]) + 1e-2);
    }
    return out.empty() ? 0.0 : sum / double(out.size());
}

}  // namespace stability
