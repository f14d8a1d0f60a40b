#include "VignettePass.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace vignette {

using namespace kestrel;

float vignetteGain(float r, float radius, float strength) {
    // Hermite smoothstep from `radius` to the corner (r = 1); guarded for radius -> 1.
    float span = 1.f - radius;
    float t = span > 1e-6f ? std::clamp((r - radius) / span, 0.f, 1.f) : (r >= radius ? 1.f : 0.f);
    float s = t * t * (3.f - 2.f * t);
    return 1.f - strength * s;
}

VignettePass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "Vignette", "Darkens colour towards the corners (example out-of-tree plugin)") {
    color = input("color", Format::Float3, "linear colour");
    colorOut = output("color", Format::Float3, "vignetted colour");
    param("strength", &Params::strength, 0.0, 1.0, "darkening in the corners: 0 none, 1 black");
    param("radius", &Params::radius, 0.0, 1.0,
          "normalised radius (1 = corner) where the darkening starts");
}

const VignettePass::Declaration& VignettePass::declaration() {
    static const Declaration d;
    return d;
}

void VignettePass::execute(FrameContext& ctx, PassIO& io) {
    const ImageView& in = io.input(declaration().color);
    const ImageView& out = io.output(declaration().colorOut);
    const int w = in.width(), h = in.height();
    // Radius is measured from the image centre, normalised by the half-diagonal.
    const float cx = 0.5f * float(w), cy = 0.5f * float(h);
    const float invHalfDiag = 1.f / std::max(1e-6f, std::sqrt(cx * cx + cy * cy));
    ctx.parallelRows(h, [&](int y0, int y1) {
        std::vector<float> gain(
            static_cast<size_t>(w));  // one allocation per row block, not per pixel
        for (int y = y0; y < y1; ++y) {
            const float dy = (float(y) + 0.5f - cy) * invHalfDiag;
            for (int x = 0; x < w; ++x) {
                const float dx = (float(x) + 0.5f - cx) * invHalfDiag;
                gain[size_t(x)] =
                    vignetteGain(std::sqrt(dx * dx + dy * dy), p_.radius, p_.strength);
            }
            for (int c = 0; c < 3; ++c) {
                const float* src = in.row(c, y);
                float* dst = out.row(c, y);
                for (int x = 0; x < w; ++x) {
                    float v = src[x];
                    v = std::isfinite(v) ? v : 0.f;  // NaN/Inf inputs must not poison the output
                    dst[x] = v * gain[size_t(x)];
                }
            }
        }
    });
}

}  // namespace vignette
