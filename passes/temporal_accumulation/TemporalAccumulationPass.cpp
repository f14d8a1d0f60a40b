#include "TemporalAccumulationPass.h"

#include <kestrel/PixelMath.h>

#include <vector>

using namespace kestrel;

PassDesc TemporalAccumulationPass::describe() {
    PassDesc d("TemporalAccumulation",
               "SVGF temporal filter: blends the illumination and its luminance moments with the"
               " reprojected history (alpha = max(alpha, 1/historyLength)); outputs the temporal"
               " variance. Fireflies are clamped before they enter the history.");
    d.input("color", Format::Float3, "current (demodulated) illumination")
        .optionalInput("prevColor", Format::Float3, "reprojected history illumination")
        .optionalInput("prevMoments", Format::Float2, "reprojected history moments (l, l^2)")
        .optionalInput("prevHistoryLength", Format::Float,
                       "reprojected history length; 0 (or unbound) means no history")
        .output("color", Format::Float3, "accumulated illumination")
        .output("moments", Format::Float2, "accumulated luminance moments (l, l^2)")
        .output("historyLength", Format::Float,
                "min(maxHistoryLength, prev + 1), 1 without history")
        .output("variance", Format::Float, "temporal luminance variance max(0, m2 - m1^2)")
        .paramFloat("alpha", 0.2, 0.0, 1.0, "minimum blend weight of the current colour")
        .paramFloat("momentsAlpha", 0.2, 0.0, 1.0, "minimum blend weight of the current moments")
        .paramFloat("maxHistoryLength", 32.0, 1.0, 1e6, "cap of the history length")
        .paramFloat("fireflySigma", 3.0, 0.0, 1e6,
                    "firefly clamp: a sample brighter than mean + k*stddev of its 8 neighbours AND"
                    " of its own history is scaled down to that bound (k = this; 0 = off)");
    return d;
}

TemporalAccumulationPass::TemporalAccumulationPass(const ParamValues& p)
    : alpha_(p.getFloat("alpha")),
      momentsAlpha_(p.getFloat("momentsAlpha")),
      maxHistory_(p.getFloat("maxHistoryLength")),
      fireflySigma_(p.getFloat("fireflySigma")) {}

void TemporalAccumulationPass::execute(FrameContext& ctx, PassIO& io) {
    const int w = ctx.extent.width, h = ctx.extent.height;
    const ImageView& color = io.input("color");
    const bool hasHist = io.hasInput("prevHistoryLength");
    const ImageView* prevC = hasHist && io.hasInput("prevColor") ? &io.input("prevColor") : nullptr;
    const ImageView* prevM =
        hasHist && io.hasInput("prevMoments") ? &io.input("prevMoments") : nullptr;
    const ImageView* prevH = hasHist ? &io.input("prevHistoryLength") : nullptr;
    const ImageView& outC = io.output("color");
    const ImageView* outM = io.hasOutput("moments") ? &io.output("moments") : nullptr;
    const ImageView* outH = io.hasOutput("historyLength") ? &io.output("historyLength") : nullptr;
    const ImageView* outV = io.hasOutput("variance") ? &io.output("variance") : nullptr;

    // Sanitised luminance of the current frame, for the firefly clamp's neighbourhood.
    std::vector<float> lum(ctx.extent.pixels());
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const float *r = color.row(0, y), *g = color.row(1, y), *b = color.row(2, y);
            float* l = lum.data() + size_t(y) * size_t(w);
            for (int x = 0; x < w; ++x)
                l[x] = px::luminance(px::sanitize(r[x]), px::sanitize(g[x]), px::sanitize(b[x]));
        }
    });

    const float k = fireflySigma_, cap = maxHistory_;
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const float* lrow = lum.data() + size_t(y) * size_t(w);
            for (int x = 0; x < w; ++x) {
                float c[3] = {px::sanitize(color.at(0, x, y)), px::sanitize(color.at(1, x, y)),
                              px::sanitize(color.at(2, x, y))};
                float l = lrow[x];
                const float hPrev = prevH ? px::sanitizePositive(prevH->at(0, x, y), 1e6f) : 0.f;
                const bool valid = hPrev > 0.f;
                float m1p = 0.f, m2p = 0.f;
                if (valid && prevM) {
                    m1p = px::sanitize(prevM->at(0, x, y));
                    m2p = px::sanitizePositive(prevM->at(1, x, y), 1e32f);
                }
                if (k > 0.f && l > 0.f) {
                    // Neighbourhood statistics exclude the centre: a lone firefly cannot raise
                    // its own bound (design.md section 7, lesson 3).
                    float s1 = 0.f, s2 = 0.f;
                    int n = 0;
                    for (int j = -1; j <= 1; ++j) {
                        const int yy = y + j;
                        if (yy < 0 || yy >= h) continue;
                        const float* lr = lum.data() + size_t(yy) * size_t(w);
                        for (int i = -1; i <= 1; ++i) {
                            const int xx = x + i;
                            if ((i == 0 && j == 0) || xx < 0 || xx >= w) continue;
                            s1 += lr[xx];
                            s2 += lr[xx] * lr[xx];
                            ++n;
                        }
                    }
                    float bound = 1e30f;  // no neighbours (1x1 image): nothing to compare with
                    if (n > 0) {
                        const float mu = s1 / float(n);
                        bound = mu + k * std::sqrt(std::max(0.f, s2 / float(n) - mu * mu));
                    }
                    // Only an outlier against its own history as well is clamped: fewer false
                    // positives in sparse 1-spp regions where every lit sample looks isolated.
                    if (valid && prevM)
                        bound =
                            std::max(bound, m1p + k * std::sqrt(std::max(0.f, m2p - m1p * m1p)));
                    if (l > bound) {
                        const float s = std::max(bound, 0.f) / l;
                        for (float& v : c) v *= s;
                        l = std::max(bound, 0.f);
                    }
                }
                const float hl = valid ? std::min(cap, hPrev + 1.f) : 1.f;
                const float ac = std::max(alpha_, 1.f / hl), am = std::max(momentsAlpha_, 1.f / hl);
                for (int ch = 0; ch < 3; ++ch) {
                    float v = c[ch];
                    if (valid && prevC) {
                        const float p = px::sanitize(prevC->at(ch, x, y));
                        v = p + ac * (v - p);
                    }
                    outC.at(ch, x, y) = v;
                }
                float m1 = l, m2 = l * l;
                if (valid && prevM) {
                    m1 = m1p + am * (m1 - m1p);
                    m2 = m2p + am * (m2 - m2p);
                }
                if (outM) {
                    outM->at(0, x, y) = m1;
                    outM->at(1, x, y) = m2;
                }
                if (outH) outH->at(0, x, y) = hl;
                if (outV) outV->at(0, x, y) = std::max(0.f, m2 - m1 * m1);
            }
        }
    });
}
