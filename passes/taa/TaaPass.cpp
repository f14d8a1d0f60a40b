#include "TaaPass.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

namespace kestrel::passes {

namespace {

constexpr float kMaxValue = 1e18f;  // keeps 3x3 sums of squares finite

float sanitise(float v) {
    return v == v ? std::clamp(v, -kMaxValue, kMaxValue) : 0.f;
}

// YCoCg (Malvar & Sullivan 2003): a luma/chroma basis where the neighbourhood box fits the
// colour distribution more tightly than RGB (Karis 2014).
struct Ycc {
    float y, co, cg;
};
inline Ycc toYcc(float r, float g, float b) {
    return {0.25f * r + 0.5f * g + 0.25f * b, 0.5f * r - 0.5f * b,
            -0.25f * r + 0.5f * g - 0.25f * b};
}
inline void fromYcc(const float v[3], float& r, float& g, float& b) {
    r = v[0] + v[1] - v[2];
    g = v[0] + v[2];
    b = v[0] - v[1] - v[2];
}

}  // namespace

PassDesc TaaPass::describe() {
    PassDesc d("TAA",
               "Temporal anti-aliasing: blends the reprojected previous output, clipped to the "
               "current 3x3 neighbourhood in YCoCg, with the current colour");
    d.input("color", Format::Float3, "current frame colour")
        .optionalInput("history", Format::Float3,
                       "previous TAA output reprojected to this frame (Catmull-Rom resampled)")
        .optionalInput("historyLength", Format::Float,
                       "reprojection validity: 0 where disoccluded (history dropped there)")
        .output("color", Format::Float3, "anti-aliased colour (feed back through a history edge)")
        .paramFloat("alpha", 0.1, 0.0, 1.0, "weight of the current frame in the blend")
        .paramFloat("gamma", 1.0, 0.0, 100.0,
                    "neighbourhood box half-width in standard deviations (variance clipping)")
        .paramEnum("mode", "clip", {"clip", "clamp"},
                   "clip: move the history towards the mean onto the box; clamp: per channel")
        .paramBool("antiFlicker", true,
                   "inverse-luminance blend weights (Karis 2014): damps flicker of bright pixels");
    return d;
}

TaaPass::TaaPass(const ParamValues& params)
    : alpha_(params.getFloat("alpha")),
      gamma_(params.getFloat("gamma")),
      clip_(params.getString("mode") == "clip"),
      antiFlicker_(params.getBool("antiFlicker")) {}

void TaaPass::resolve(ResolveContext& rc) {
    if (!rc.isBound("history")) {
        rc.forward("color", "color");
        rc.note("no history bound: TAA passes the current colour through");
    }
}

void TaaPass::execute(FrameContext& ctx, PassIO& io) {
    const ImageView& cur = io.input("color");
    const ImageView& out = io.output("color");
    const int w = cur.width(), h = cur.height();
    const ImageView* hist = io.hasInput("history") ? &io.input("history") : nullptr;
    const ImageView* len = io.hasInput("historyLength") ? &io.input("historyLength") : nullptr;

    // The current frame in YCoCg, sanitised, one plane per channel.
    // Scratch, fully written below: no zero-fill (std::vector would memset 3 planes).
    std::unique_ptr<float[]> yccBuf(new float[size_t(w) * size_t(h) * 3]);
    float* const ycc = yccBuf.get();
    const size_t plane = size_t(w) * size_t(h);
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const float *r = cur.row(0, y), *g = cur.row(1, y), *b = cur.row(2, y);
            float* dy = ycc + size_t(y) * w;
            for (int x = 0; x < w; ++x) {
                Ycc v = toYcc(sanitise(r[x]), sanitise(g[x]), sanitise(b[x]));
                dy[x] = v.y;
                dy[plane + x] = v.co;
                dy[2 * plane + x] = v.cg;
            }
        }
    });

    const float alpha = alpha_, gamma = gamma_;
    const bool clip = clip_, antiFlicker = antiFlicker_;
    // One pixel's TAA from its 3x3 neighbourhood sums. Pure per-lane arithmetic, identical
    // for the border path (generic) and the interior row loop (vectorised by the compiler).
    auto resolvePixel = [=](const float c[3], const float s1[3], const float s2[3], float n,
                            float hv[3], float res[3]) {
        float mu[3], lo[3], hi[3];
        for (int ch = 0; ch < 3; ++ch) {
            const float m1 = s1[ch] / n;
            const float ext = gamma * std::sqrt(std::max(0.f, s2[ch] / n - m1 * m1));
            mu[ch] = c[ch] + m1;
            // The box always contains the current colour: a lone bright pixel is
            // outside its own mean +- sigma, and clipping it would make TAA dim
            // every small feature (a static scene must converge to the input).
            lo[ch] = std::min(mu[ch] - ext, c[ch]);
            hi[ch] = std::max(mu[ch] + ext, c[ch]);
        }
        if (clip) {
            // Move H towards mu until it is inside the box (Pedersen 2016);
            // mu lies inside, so t stays in [0, 1]. Selects instead of branches (vectorises);
            // an unselected quotient may be Inf/NaN and is discarded.
            float t = 1.f;
            for (int ch = 0; ch < 3; ++ch) {
                const float off = hv[ch] - mu[ch];
                const float tHi = std::min(t, (hi[ch] - mu[ch]) / off);
                t = hv[ch] > hi[ch] ? tHi : t;
                const float tLo = std::min(t, (lo[ch] - mu[ch]) / off);
                t = hv[ch] < lo[ch] ? tLo : t;
            }
            for (int ch = 0; ch < 3; ++ch) hv[ch] = mu[ch] + (hv[ch] - mu[ch]) * t;
        } else {
            for (int ch = 0; ch < 3; ++ch) hv[ch] = std::clamp(hv[ch], lo[ch], hi[ch]);
        }
        float wc = alpha, wh = 1.f - alpha;
        if (antiFlicker) {
            wc /= 1.f + std::max(0.f, c[0]);
            wh /= 1.f + std::max(0.f, hv[0]);
        }
        const float sum = wc + wh;
        const bool pos = sum > 0.f;
        const float wcn = wc / sum, whn = wh / sum;
        wc = pos ? wcn : 1.f;
        wh = pos ? whn : 0.f;
        for (int ch = 0; ch < 3; ++ch) res[ch] = wc * c[ch] + wh * hv[ch];
    };

    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const float *cr = cur.row(0, y), *cg = cur.row(1, y), *cb = cur.row(2, y);
            float *o0 = out.row(0, y), *o1 = out.row(1, y), *o2 = out.row(2, y);
            if (!hist) {  // no history: exactly the current colour
                for (int x = 0; x < w; ++x) {
                    o0[x] = sanitise(cr[x]);
                    o1[x] = sanitise(cg[x]);
                    o2[x] = sanitise(cb[x]);
                }
                continue;
            }
            const int ya = std::max(0, y - 1), yb = std::min(h - 1, y + 1);
            const float* lenRow = len ? len->row(0, y) : nullptr;
            const float *hr = hist->row(0, y), *hg = hist->row(1, y), *hb = hist->row(2, y);
            // Generic pixel (image borders): clamped 3x3 window.
            auto generic = [&](int x) {
                const size_t i = size_t(y) * w + x;
                const float c[3] = {ycc[i], ycc[plane + i], ycc[2 * plane + i]};
                const bool valid = (!lenRow || lenRow[x] > 0.f) && std::isfinite(hr[x]) &&
                                   std::isfinite(hg[x]) && std::isfinite(hb[x]);
                if (!valid) {  // disoccluded: exactly the current colour
                    o0[x] = sanitise(cr[x]);
                    o1[x] = sanitise(cg[x]);
                    o2[x] = sanitise(cb[x]);
                    return;
                }
                Ycc v = toYcc(sanitise(hr[x]), sanitise(hg[x]), sanitise(hb[x]));
                float hv[3] = {v.y, v.co, v.cg}, res[3];
                // 3x3 mean and standard deviation, shifted by the centre for precision.
                const int xa = std::max(0, x - 1), xb = std::min(w - 1, x + 1);
                const float n = float((yb - ya + 1) * (xb - xa + 1));
                float s1[3], s2[3];
                for (int ch = 0; ch < 3; ++ch) {
                    const float* p = ycc + size_t(ch) * plane;
                    float a1 = 0, a2 = 0;
                    for (int yy = ya; yy <= yb; ++yy)
                        for (int xx = xa; xx <= xb; ++xx) {
                            float d = p[size_t(yy) * w + xx] - c[ch];
                            a1 += d;
                            a2 += d * d;
                        }
                    s1[ch] = a1;
                    s2[ch] = a2;
                }
                resolvePixel(c, s1, s2, n, hv, res);
                fromYcc(res, o0[x], o1[x], o2[x]);
            };
            if (y == 0 || y == h - 1 || w < 3) {
                for (int x = 0; x < w; ++x) generic(x);
                continue;
            }
            generic(0);
            // Interior: the same arithmetic in the same order with a fixed 3x3 window and no
            // branches, so the compiler vectorises it across x.
            const float* rows[3][3];
            for (int ch = 0; ch < 3; ++ch)
                for (int r = 0; r < 3; ++r)
                    rows[ch][r] = ycc + size_t(ch) * plane + size_t(y - 1 + r) * w;
            for (int x = 1; x < w - 1; ++x) {
                float c[3], s1[3], s2[3];
                for (int ch = 0; ch < 3; ++ch) {
                    c[ch] = rows[ch][1][x];
                    float a1 = 0, a2 = 0;
                    for (int r = 0; r < 3; ++r)
                        for (int k = -1; k <= 1; ++k) {
                            float d = rows[ch][r][x + k] - c[ch];
                            a1 += d;
                            a2 += d * d;
                        }
                    s1[ch] = a1;
                    s2[ch] = a2;
                }
                const bool valid = (!lenRow || lenRow[x] > 0.f) &&
                                   std::fabs(hr[x]) <= std::numeric_limits<float>::max() &&
                                   std::fabs(hg[x]) <= std::numeric_limits<float>::max() &&
                                   std::fabs(hb[x]) <= std::numeric_limits<float>::max();
                Ycc v = toYcc(sanitise(hr[x]), sanitise(hg[x]), sanitise(hb[x]));
                float hv[3] = {v.y, v.co, v.cg}, res[3];
                resolvePixel(c, s1, s2, 9.f, hv, res);
                float r, g, b;
                fromYcc(res, r, g, b);
                o0[x] = valid ? r : sanitise(cr[x]);
                o1[x] = valid ? g : sanitise(cg[x]);
                o2[x] = valid ? b : sanitise(cb[x]);
            }
            generic(w - 1);
        }
    });
}

}  // namespace kestrel::passes
