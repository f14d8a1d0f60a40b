#include "PixelJitter.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "kestrel/Conventions.h"

namespace kestrel::exr {

float depthJitterScore(const float* depth, int w, int h) {
    auto inv = [](float z) {  // 1/z of a surface pixel; 0 for background or invalid depth
        return z > 0.f && z < 0.1f * kBackgroundDepth ? 1.f / z : 0.f;
    };
    std::vector<float> ratios;
    for (int y = 1; y + 1 < h; y += 2) {
        const float *r0 = depth + size_t(y - 1) * size_t(w), *r1 = r0 + w, *r2 = r1 + w;
        for (int x = 1; x + 1 < w; x += 2) {
            const float c = inv(r1[x]);
            const float l = inv(r1[x - 1]), r = inv(r1[x + 1]), u = inv(r0[x]), d = inv(r2[x]);
            if (c == 0.f || l == 0.f || r == 0.f || u == 0.f || d == 0.f) continue;
            const float gx = std::fabs(r - l) * 0.5f, gy = std::fabs(d - u) * 0.5f;
            // Relative to the local 1/z, so a gradient lost in rounding is not a signal.
            const float floor = 1e-5f * c;
            if (gx > floor) ratios.push_back(std::fabs(l - 2.f * c + r) / gx);
            if (gy > floor) ratios.push_back(std::fabs(u - 2.f * c + d) / gy);
        }
    }
    if (ratios.size() < 16) return 0.f;
    auto mid = ratios.begin() + std::ptrdiff_t(ratios.size() / 2);
    std::nth_element(ratios.begin(), mid, ratios.end());
    return *mid;
}

AntiAliasing decideBlenderAntiAliasing(std::optional<float> score) {
    if (score && *score > kJitterThreshold) return decideAntiAliasing(std::nullopt, score);
    char measured[96] = "no depth to measure";
    if (score)
        std::snprintf(measured, sizeof measured,
                      "depth jitter score %.3g, samples at pixel centres", double(*score));
    char why[480];
    std::snprintf(why, sizeof why,
                  "anti-aliased render assumed: Blender's default %g px pixel filter (%s, as "
                  "Cycles writes them at 1 spp with any filter: the data cannot tell, and no "
                  "camera.json states the filter); set input.antiAliased=false for a render "
                  "with a pixel filter of 1 px or less",
                  double(kBlenderDefaultFilterWidth), measured);
    return {true, why};
}

AntiAliasing decideAntiAliasing(std::optional<float> stated, std::optional<float> score) {
    char why[160];
    if (stated) {
        const bool aa = *stated > 1.f;
        std::snprintf(why, sizeof why, "%s render (the source states a %g px pixel filter)",
                      aa ? "anti-aliased" : "point-sampled", double(*stated));
        return {aa, why};
    }
    if (score) {
        const bool aa = *score > kJitterThreshold;
        std::snprintf(why, sizeof why, "%s render (depth jitter score %.3g, threshold %g)",
                      aa ? "anti-aliased" : "point-sampled", double(*score),
                      double(kJitterThreshold));
        return {aa, why};
    }
    return {false,
            "point-sampled render assumed (no stated pixel filter, no readable depth to measure)"};
}

}  // namespace kestrel::exr
