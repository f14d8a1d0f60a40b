#include "AlbedoResolvePass.h"

#include <kestrel/Conventions.h>
#include <kestrel/PixelMath.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <vector>

using namespace kestrel;

PassDesc AlbedoResolvePass::describe() {
    PassDesc d("AlbedoResolve",
               "The albedo to demodulate by: accumulated over frames where the G-buffer jitters "
               "(a pixel filter wider than a pixel), this frame's albedo elsewhere");
    d.input("albedo", Format::Float3, "this frame's albedo")
        .input("depth", Format::Float, "linear depth (measures the jitter)")
        .optionalInput("history", Format::Float3, "last frame's resolved albedo, reprojected")
        .optionalInput("historyLength", Format::Float, "reprojected history length, 0 disoccluded")
        .output("albedo", Format::Float3, "albedo for Demodulate and Modulate")
        .output("historyLength", Format::Float, "history length (feed back to the reprojection)")
        .paramEnum("mode", "auto", {"auto", "accumulate", "current"},
                   "auto: accumulate when the depth jitters; accumulate or current: always")
        .paramFloat("alpha", 0.1, 0.0, 1.0, "minimum blend weight of this frame's albedo")
        .paramFloat("maxHistoryLength", 32.0, 1.0, 1e6, "cap of the history length")
        .paramFloat("jitterThreshold", 0.05, 0.0, 1e6,
                    "jitter score above which auto accumulates (un-jittered renders score ~1e-3, "
                    "a 1.5 px filter ~0.5)");
    return d;
}

AlbedoResolvePass::AlbedoResolvePass(const ParamValues& p)
    : alpha_(p.getFloat("alpha")),
      maxHistory_(p.getFloat("maxHistoryLength")),
      threshold_(p.getFloat("jitterThreshold")),
      mode_(p.getString("mode")) {}

void AlbedoResolvePass::resolve(ResolveContext& rc) {
    if (mode_ == "current") {
        rc.forward("albedo", "albedo");
        rc.note("mode current: this frame's albedo");
    }
}

float AlbedoResolvePass::jitterScore(const ImageView& depth) {
    const int w = depth.width(), h = depth.height();
    std::vector<float> ratios;
    auto inv = [](float z) {  // 1/z of a surface pixel, 0 for background or invalid depth
        return z > 0.f && z < 0.1f * kBackgroundDepth && std::isfinite(z) ? 1.f / z : 0.f;
    };
    // Every other row and column: enough pixels for a stable median, a quarter of the work.
    for (int y = 1; y + 1 < h; y += 2) {
        const float *r0 = depth.row(0, y - 1), *r1 = depth.row(0, y), *r2 = depth.row(0, y + 1);
        for (int x = 1; x + 1 < w; x += 2) {
            const float c = inv(r1[x]);
            const float l = inv(r1[x - 1]), r = inv(r1[x + 1]), u = inv(r0[x]), d = inv(r2[x]);
            if (c == 0.f || l == 0.f || r == 0.f || u == 0.f || d == 0.f) continue;
            const float gx = std::fabs(r - l) * 0.5f, gy = std::fabs(d - u) * 0.5f;
            const float sx = std::fabs(l - 2.f * c + r), sy = std::fabs(u - 2.f * c + d);
            // Relative to the local 1/z, so a gradient lost in rounding is not a signal.
            const float floor = 1e-5f * c;
            if (gx > floor) ratios.push_back(sx / gx);
            if (gy > floor) ratios.push_back(sy / gy);
        }
    }
    if (ratios.size() < 16) return 0.f;
    auto mid = ratios.begin() + std::ptrdiff_t(ratios.size() / 2);
    std::nth_element(ratios.begin(), mid, ratios.end());
    return *mid;
}

void AlbedoResolvePass::execute(FrameContext& ctx, PassIO& io) {
    const ImageView& cur = io.input("albedo");
    const ImageView& out = io.output("albedo");
    const ImageView* outLen = io.hasOutput("historyLength") ? &io.output("historyLength") : nullptr;
    const ImageView* hist = io.hasInput("history") ? &io.input("history") : nullptr;
    const ImageView* len = io.hasInput("historyLength") ? &io.input("historyLength") : nullptr;
    bool accumulate = mode_ == "accumulate";
    if (mode_ == "auto") {
        const float filter = ctx.scene ? ctx.scene->pixelFilterWidth : 0.f;
        const float score = jitterScore(io.input("depth"));
        accumulate = filter > 1.f || score > threshold_;
        if (int(accumulate) != lastDecision_)
            spdlog::info("AlbedoResolve: frame {}: pixel filter {} px, depth jitter score {:.3g} "
                         "(threshold {}): {}",
                         ctx.frameNumber, filter, score, threshold_,
                         accumulate ? "anti-aliased render, accumulating the albedo"
                                    : "point-sampled render, this frame's albedo");
        lastDecision_ = int(accumulate);
    }
    const int w = cur.width();
    ctx.parallelRows(cur.height(), [&](int ya, int yb) {
        for (int y = ya; y < yb; ++y) {
            const float* l = len && accumulate ? len->row(0, y) : nullptr;
            float* ol = outLen ? outLen->row(0, y) : nullptr;
            for (int x = 0; x < w; ++x) {
                const float prev = l && hist ? px::sanitize(l[x]) : 0.f;
                const float n = prev > 0.f ? std::min(prev + 1.f, maxHistory_) : 1.f;
                // Blend weight of this frame (SVGF's temporal accumulation, eq. 1 with
                // alpha = max(alpha, 1/n)): the plain mean while the history is short.
                const float a = std::max(alpha_, 1.f / n);
                for (int c = 0; c < 3; ++c) {
                    const float v = px::sanitize(cur.row(c, y)[x]);
                    const float hv = prev > 0.f ? px::sanitize(hist->row(c, y)[x]) : v;
                    out.row(c, y)[x] = px::sanitize(hv + a * (v - hv));
                }
                if (ol) ol[x] = n;
            }
        }
    });
}
