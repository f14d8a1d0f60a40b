#include "HistoryFixPass.h"

#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

using namespace kestrel;

namespace {

/// B3-spline taps (as A-Trous): a smooth footprint, the centre weighted most.
constexpr float kKernel[5] = {1.f / 16, 1.f / 4, 3.f / 8, 1.f / 4, 1.f / 16};

struct Planes {
    const ImageView &color, &length, &depth, &normal;
    const ImageView* ids;
};

/// The depth slope through a pixel from its neighbours' differences b and f: the smaller where
/// both agree in sign (a slope, or a slope beside a depth edge), else 0 (a ridge, a valley, a
/// pixel standing alone in front of a wall, whose differences are no slope at all).
float slope(float prev, float cur, float next, bool hasPrev, bool hasNext) {
    const float b = hasPrev ? cur - prev : 0.f, f = hasNext ? next - cur : 0.f;
    if (!hasPrev) return f;
    if (!hasNext) return b;
    if ((b > 0.f) != (f > 0.f)) return 0.f;
    return std::fabs(b) <= std::fabs(f) ? b : f;
}

/// The stride for a history length: `stride` at 1, falling linearly to 0 at `frames`.
int strideFor(float hl, const HistoryFixPass::Settings& s) {
    if (!(hl < s.frames) || s.frames <= 1.f) return 0;
    const float t = (s.frames - std::max(hl, 1.f)) / (s.frames - 1.f);
    return int(std::lround(t * float(s.stride)));
}

/// The filled colour of pixel (x, y) with tap spacing `step` > 0, into out[3].
void fillPixel(const Planes& p, const HistoryFixPass::Settings& s, int x, int y, int step,
               float out[3]) {
    const int w = p.color.width(), h = p.color.height();
    auto z = [&](int xx, int yy) { return px::sanitizeDepth(p.depth.at(0, xx, yy)); };
    auto n = [&](int c, int xx, int yy) { return px::sanitizeNormal(p.normal.at(c, xx, yy)); };
    const float zp = z(x, y);
    const bool l = x > 0, r = x + 1 < w, u = y > 0, d = y + 1 < h;
    const float gx = slope(l ? z(x - 1, y) : 0, zp, r ? z(x + 1, y) : 0, l, r);
    const float gy = slope(u ? z(x, y - 1) : 0, zp, d ? z(x, y + 1) : 0, u, d);
    const int32_t id = p.ids ? p.ids->atInt(x, y) : 0;
    float sw = 0.f, sc[3] = {0.f, 0.f, 0.f};
    for (int j = -2; j <= 2; ++j)
        for (int i = -2; i <= 2; ++i) {
            const int dx = i * step, dy = j * step, xq = x + dx, yq = y + dy;
            if (xq < 0 || xq >= w || yq < 0 || yq >= h) continue;
            float wt = kKernel[i + 2] * kKernel[j + 2];
            if (i != 0 || j != 0) {
                if (p.ids && p.ids->atInt(xq, yq) != id) continue;
                const float zq = z(xq, yq);
                if (zq >= kBackgroundDepth) continue;
                // The depth the surface's slope predicts there, within depthSlack of the depth
                // per pixel of distance (a plane seen at a grazing angle, a gentle curve).
                const float predicted = zp + gx * float(dx) + gy * float(dy);
                const float tolerance = s.depthSlack * zp * float(std::abs(dx) + std::abs(dy));
                if (!(std::fabs(zq - predicted) <= tolerance)) continue;
                const float dot = n(0, x, y) * n(0, xq, yq) + n(1, x, y) * n(1, xq, yq) +
                                  n(2, x, y) * n(2, xq, yq);
                if (!(dot > 0.f)) continue;
                wt *= std::pow(std::min(dot, 1.f), s.normalPower);
            }
            // Each tap counts as the samples its history holds (its noise falls as 1 / length).
            wt *= px::sanitizePositive(p.length.at(0, xq, yq), 1e6f) + 1e-3f;
            sw += wt;
            for (int c = 0; c < 3; ++c) sc[c] += wt * px::sanitize(p.color.at(c, xq, yq));
        }
    for (int c = 0; c < 3; ++c) out[c] = sc[c] / sw;  // sw > 0: the centre always counts
}

}  // namespace

PassDesc HistoryFixPass::describe() {
    PassDesc d("HistoryFix",
               "Fills pixels with a short history (disocclusions, cuts, the first frames, a "
               "history anti-lag shortened) from their neighbours on the same surface: a 5x5 "
               "B3-spline footprint whose stride shrinks from `stride` at historyLength 1 to 0 "
               "at `frames`, weighted by depth, normal, object id and each neighbour's history "
               "length, never by luminance (after NRD ReBLUR's history fix). Other pixels pass "
               "unchanged.");
    d.input("color", Format::Float3, "temporally accumulated illumination")
        .input("historyLength", Format::Float, "history length per pixel (1: no history)")
        .input("depth", Format::Float, "linear view depth")
        .input("normal", Format::Float3, "world-space normal")
        .optionalInput("objectId", Format::Int32, "object id: taps on another object are skipped")
        .output("color", Format::Float3, "the illumination, filled where the history is short")
        .paramFloat("frames", 4.0, 1.0, 1e6,
                    "pixels whose history is shorter are filled (4: VarianceEstimation's "
                    "minHistoryLength, below which the variance is spatial too)")
        .paramInt("stride", 1, 1, 64,
                  "tap spacing in pixels at historyLength 1 (the footprint is 4 strides wide)")
        .paramFloat("normalPower", 8.0, 0.0, 1e4,
                    "normal weight exponent: max(0, n_p . n_q)^p (looser than A-Trous' 128: a "
                    "curved surface's neighbours must count)")
        .paramFloat("depthSlack", 0.01, 0.0, 1e6,
                    "relative depth tolerance per pixel of distance, beyond the depth slope");
    return d;
}

HistoryFixPass::HistoryFixPass(const ParamValues& p)
    : s_{p.getFloat("frames"), int(p.getInt("stride")), p.getFloat("normalPower"),
         p.getFloat("depthSlack")} {}

void HistoryFixPass::execute(FrameContext& ctx, PassIO& io) {
    const Planes p{io.input("color"), io.input("historyLength"), io.input("depth"),
                   io.input("normal"), io.hasInput("objectId") ? &io.input("objectId") : nullptr};
    const ImageView& out = io.output("color");
    const int w = ctx.extent.width;
    ctx.parallelRows(ctx.extent.height, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int x = 0; x < w; ++x) {
                const float hl = px::sanitizePositive(p.length.at(0, x, y), 1e6f);
                const int step = strideFor(hl, s_);
                float c[3];
                if (step > 0 && px::sanitizeDepth(p.depth.at(0, x, y)) < kBackgroundDepth) {
                    fillPixel(p, s_, x, y, step, c);
                } else {
                    for (int k = 0; k < 3; ++k) c[k] = px::sanitize(p.color.at(k, x, y));
                }
                for (int k = 0; k < 3; ++k) out.at(k, x, y) = c[k];
            }
    });
}
