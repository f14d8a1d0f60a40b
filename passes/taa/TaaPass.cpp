#include "TaaPass.h"

#include <algorithm>
#include <cmath>
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
    std::vector<float> ycc(size_t(w) * size_t(h) * 3);
    const size_t plane = size_t(w) * size_t(h);
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const float *r = cur.row(0, y), *g = cur.row(1, y), *b = cur.row(2, y);
            float* dy = ycc.data() + size_t(y) * w;
            for (int x = 0; x < w; ++x) {
                Ycc v = toYcc(sanitise(r[x]), sanitise(g[x]), sanitise(b[x]));
                dy[x] = v.y;
                dy[plane + x] = v.co;
                dy[2 * plane + x] = v.cg;
            }
        }
    });

    const float alpha = alpha_, gamma = gamma_;
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const int ya = std::max(0, y - 1), yb = std::min(h - 1, y + 1);
            const float* lenRow = len ? len->row(0, y) : nullptr;
            for (int x = 0; x < w; ++x) {
                const size_t i = size_t(y) * w + x;
                const float c[3] = {ycc[i], ycc[plane + i], ycc[2 * plane + i]};
                float res[3];

                bool valid = hist && (!lenRow || lenRow[x] > 0.f);
                float hv[3] = {0, 0, 0};
                if (valid) {
                    const float hr = hist->row(0, y)[x], hg = hist->row(1, y)[x],
                                hb = hist->row(2, y)[x];
                    valid = std::isfinite(hr) && std::isfinite(hg) && std::isfinite(hb);
                    Ycc v = toYcc(sanitise(hr), sanitise(hg), sanitise(hb));
                    hv[0] = v.y, hv[1] = v.co, hv[2] = v.cg;
                }
                if (!valid) {  // disoccluded or no history: exactly the current colour
                    for (int ch = 0; ch < 3; ++ch) out.row(ch, y)[x] = sanitise(cur.row(ch, y)[x]);
                    continue;
                }
                {
                    // 3x3 mean and standard deviation, shifted by the centre for precision.
                    const int xa = std::max(0, x - 1), xb = std::min(w - 1, x + 1);
                    const float n = float((yb - ya + 1) * (xb - xa + 1));
                    float mu[3], lo[3], hi[3];
                    for (int ch = 0; ch < 3; ++ch) {
                        const float* p = ycc.data() + size_t(ch) * plane;
                        float s1 = 0, s2 = 0;
                        for (int yy = ya; yy <= yb; ++yy)
                            for (int xx = xa; xx <= xb; ++xx) {
                                float d = p[size_t(yy) * w + xx] - c[ch];
                                s1 += d;
                                s2 += d * d;
                            }
                        const float m1 = s1 / n;
                        const float ext = gamma * std::sqrt(std::max(0.f, s2 / n - m1 * m1));
                        mu[ch] = c[ch] + m1;
                        // The box always contains the current colour: a lone bright pixel is
                        // outside its own mean +- sigma, and clipping it would make TAA dim
                        // every small feature (a static scene must converge to the input).
                        lo[ch] = std::min(mu[ch] - ext, c[ch]);
                        hi[ch] = std::max(mu[ch] + ext, c[ch]);
                    }
                    if (clip_) {
                        // Move H towards mu until it is inside the box (Pedersen 2016);
                        // mu lies inside, so t stays in [0, 1].
                        float t = 1.f;
                        for (int ch = 0; ch < 3; ++ch) {
                            const float off = hv[ch] - mu[ch];
                            if (hv[ch] > hi[ch]) t = std::min(t, (hi[ch] - mu[ch]) / off);
                            if (hv[ch] < lo[ch]) t = std::min(t, (lo[ch] - mu[ch]) / off);
                        }
                        for (int ch = 0; ch < 3; ++ch) hv[ch] = mu[ch] + (hv[ch] - mu[ch]) * t;
                    } else {
                        for (int ch = 0; ch < 3; ++ch) hv[ch] = std::clamp(hv[ch], lo[ch], hi[ch]);
                    }
                    float wc = alpha, wh = 1.f - alpha;
                    if (antiFlicker_) {
                        wc /= 1.f + std::max(0.f, c[0]);
                        wh /= 1.f + std::max(0.f, hv[0]);
                    }
                    const float sum = wc + wh;
                    if (sum > 0.f) {
                        wc /= sum;
                        wh /= sum;
                    } else {
                        wc = 1.f, wh = 0.f;
                    }
                    for (int ch = 0; ch < 3; ++ch) res[ch] = wc * c[ch] + wh * hv[ch];
                }
                fromYcc(res, out.row(0, y)[x], out.row(1, y)[x], out.row(2, y)[x]);
            }
        }
    });
}

}  // namespace kestrel::passes
