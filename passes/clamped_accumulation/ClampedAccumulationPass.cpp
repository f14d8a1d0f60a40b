#include "ClampedAccumulationPass.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace kestrel::passes {

namespace {

// Inputs are clamped to this magnitude: squares of 49+ window samples then stay finite.
constexpr float kMaxValue = 1e18f;

float sanitise(float v) {
    return v == v ? std::clamp(v, -kMaxValue, kMaxValue) : 0.f;
}

}  // namespace

PassDesc ClampedAccumulationPass::describe() {
    PassDesc d("ClampedAccumulation",
               "GAMES202 temporal accumulation: alpha*C + (1-alpha)*clamp(history, mu-k*sigma, "
               "mu+k*sigma) over a window of the current colour");
    d.input("color", Format::Float3, "current (spatially filtered) colour")
        .optionalInput("history", Format::Float3, "previous output reprojected to this frame")
        .optionalInput("historyLength", Format::Float,
                       "reprojection validity: 0 where the projection failed (alpha = 1 there)")
        .output("color", Format::Float3, "accumulated colour")
        .paramFloat("alpha", 0.2, 0.0, 1.0, "weight of the current colour where history is valid")
        .paramFloat("k", 1.0, 0.0, 1000.0, "half-width of the colour box in standard deviations")
        .paramInt("radius", 3, 0, 32, "window radius of the mean/sigma statistics (3: 7x7)");
    return d;
}

ClampedAccumulationPass::ClampedAccumulationPass(const ParamValues& params)
    : alpha_(params.getFloat("alpha")),
      k_(params.getFloat("k")),
      radius_(int(params.getInt("radius"))) {}

void ClampedAccumulationPass::resolve(ResolveContext& rc) {
    if (!rc.isBound("history")) {
        rc.forward("color", "color");
        rc.note("no history bound: the output is the current colour");
    }
}

void ClampedAccumulationPass::execute(FrameContext& ctx, PassIO& io) {
    const ImageView& cur = io.input("color");
    const ImageView& out = io.output("color");
    const int w = cur.width(), h = cur.height(), r = radius_;
    const bool hasHistory = io.hasInput("history");
    const ImageView* hist = hasHistory ? &io.input("history") : nullptr;
    const ImageView* len = io.hasInput("historyLength") ? &io.input("historyLength") : nullptr;

    if (!hasHistory) {  // first frame or no reprojection: alpha = 1 everywhere
        ctx.parallelRows(h, [&](int y0, int y1) {
            for (int c = 0; c < 3; ++c)
                for (int y = y0; y < y1; ++y) {
                    const float* s = cur.row(c, y);
                    float* d = out.row(c, y);
                    for (int x = 0; x < w; ++x) d[x] = sanitise(s[x]);
                }
        });
        return;
    }

    // Sanitised colour with r zero columns on each side and a matching in-image mask, so the
    // window loops below run over plain contiguous rows without border branches.
    const int wp = w + 2 * r;
    std::vector<float> padded(size_t(wp) * size_t(h) * 3, 0.f), mask(size_t(wp), 0.f);
    std::fill(mask.begin() + r, mask.begin() + r + w, 1.f);
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int c = 0; c < 3; ++c)
            for (int y = y0; y < y1; ++y) {
                const float* s = cur.row(c, y);
                float* d = padded.data() + (size_t(c) * h + y) * wp + r;
                for (int x = 0; x < w; ++x) d[x] = sanitise(s[x]);
            }
    });

    const float alpha = alpha_, k = k_;
    ctx.parallelRows(h, [&](int y0, int y1) {
        // Per-row sums of (C_q - C_p) and (C_q - C_p)^2: shifting by the centre value keeps
        // the variance free of the cancellation E[C^2] - E[C]^2 suffers on HDR values.
        std::vector<float> s1(size_t(w) * 3), s2(size_t(w) * 3), cnt(static_cast<size_t>(w));
        for (int y = y0; y < y1; ++y) {
            std::fill(s1.begin(), s1.end(), 0.f);
            std::fill(s2.begin(), s2.end(), 0.f);
            std::fill(cnt.begin(), cnt.end(), 0.f);
            const int ya = std::max(0, y - r), yb = std::min(h - 1, y + r);
            for (int yy = ya; yy <= yb; ++yy)
                for (int dx = -r; dx <= r; ++dx) {
                    const float* m = mask.data() + r + dx;
                    float* cn = cnt.data();
                    for (int x = 0; x < w; ++x) cn[x] += m[x];
                    for (int c = 0; c < 3; ++c) {
                        const float* centre = padded.data() + (size_t(c) * h + y) * wp + r;
                        const float* q = padded.data() + (size_t(c) * h + yy) * wp + r + dx;
                        float* a1 = s1.data() + size_t(c) * w;
                        float* a2 = s2.data() + size_t(c) * w;
                        for (int x = 0; x < w; ++x) {
                            float d = (q[x] - centre[x]) * m[x];
                            a1[x] += d;
                            a2[x] += d * d;
                        }
                    }
                }

            const float* lenRow = len ? len->row(0, y) : nullptr;
            for (int x = 0; x < w; ++x) {
                float hv[3];
                bool valid = !lenRow || lenRow[x] > 0.f;  // NaN length: invalid
                for (int c = 0; c < 3; ++c) {
                    hv[c] = hist->row(c, y)[x];
                    valid = valid && std::isfinite(hv[c]);
                }
                const float inv = 1.f / cnt[x];  // >= 1: the centre is always counted
                for (int c = 0; c < 3; ++c) {
                    const float centre = padded[(size_t(c) * h + y) * wp + r + x];
                    float result = centre;
                    if (valid) {
                        const float m1 = s1[size_t(c) * w + x] * inv;
                        const float var = std::max(0.f, s2[size_t(c) * w + x] * inv - m1 * m1);
                        const float mu = centre + m1, sigma = std::sqrt(var);
                        const float clamped = std::clamp(hv[c], mu - k * sigma, mu + k * sigma);
                        result = alpha * centre + (1.f - alpha) * clamped;
                    }
                    out.row(c, y)[x] = result;
                }
            }
        }
    });
}

}  // namespace kestrel::passes
