#include "VarianceEstimationPass.h"

#include <kestrel/PixelMath.h>

using namespace kestrel;

PassDesc VarianceEstimationPass::describe() {
    PassDesc d("VarianceEstimation",
               "Spatial variance estimate where the history is short: 7x7 cross-bilateral moments"
               " (depth, normal, luminance weights), variance boosted by 4 / historyLength; colour"
               " filtered with the same weights. Elsewhere colour and variance pass through.");
    d.input("color", Format::Float3, "temporally accumulated illumination")
        .input("moments", Format::Float2, "accumulated luminance moments (l, l^2)")
        .input("historyLength", Format::Float, "history length per pixel")
        .input("variance", Format::Float, "temporal variance")
        .input("depth", Format::Float, "linear view depth")
        .input("normal", Format::Float3, "world-space normal")
        .optionalInput("objectId", Format::Int32, "object id: taps on another object get weight 0")
        .output("color", Format::Float3, "illumination (filtered where the history is short)")
        .output("variance", Format::Float, "luminance variance")
        .paramFloat("sigmaZ", 1.0, 0.0, 1e6, "depth weight tolerance in units of the depth slope")
        .paramFloat("sigmaN", 128.0, 0.0, 1e4, "normal weight exponent")
        .paramFloat("sigmaL", 10.0, 1e-6, 1e6,
                    "luminance weight: exp(-|l_p - l_q| / sigmaL), un-normalised (Falcor phiColor)")
        .paramFloat("minHistoryLength", 4.0, 0.0, 1e6,
                    "history length below which the spatial estimate is used");
    return d;
}

VarianceEstimationPass::VarianceEstimationPass(const ParamValues& p)
    : sigmaZ_(p.getFloat("sigmaZ")),
      sigmaN_(p.getFloat("sigmaN")),
      sigmaL_(p.getFloat("sigmaL")),
      minHistory_(p.getFloat("minHistoryLength")) {}

void VarianceEstimationPass::execute(FrameContext& ctx, PassIO& io) {
    const int w = ctx.extent.width, h = ctx.extent.height;
    const ImageView& color = io.input("color");
    const ImageView& moments = io.input("moments");
    const ImageView& hist = io.input("historyLength");
    const ImageView& var = io.input("variance");
    const ImageView& depth = io.input("depth");
    const ImageView& normal = io.input("normal");
    const int32_t* ids = io.hasInput("objectId") ? io.input("objectId").ints() : nullptr;
    const ImageView& outC = io.output("color");
    const ImageView* outV = io.hasOutput("variance") ? &io.output("variance") : nullptr;
    const float sigmaZ = sigmaZ_, sigmaN = sigmaN_, invSigmaL = 1.f / sigmaL_;
    const float minHist = minHistory_;

    auto col = [&](int c, int x, int y) { return px::sanitize(color.at(c, x, y)); };
    auto lum = [&](int x, int y) {
        return px::luminance(col(0, x, y), col(1, x, y), col(2, x, y));
    };
    auto z = [&](int x, int y) { return px::sanitizeDepth(depth.at(0, x, y)); };
    auto nrm = [&](int c, int x, int y) { return px::sanitizeNormal(normal.at(c, x, y)); };

    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int x = 0; x < w; ++x) {
                const float hl = px::sanitizePositive(hist.at(0, x, y), 1e6f);
                if (hl >= minHist) {  // long history: the temporal estimate stands
                    for (int c = 0; c < 3; ++c) outC.at(c, x, y) = col(c, x, y);
                    if (outV) outV->at(0, x, y) = px::sanitizePositive(var.at(0, x, y), 1e32f);
                    continue;
                }
                const bool l = x > 0, r = x + 1 < w, u = y > 0, d = y + 1 < h;
                const float zp = z(x, y), lp = lum(x, y);
                const float gx = px::minAbsDiff(l ? z(x - 1, y) : 0, zp, r ? z(x + 1, y) : 0, l, r);
                const float gy = px::minAbsDiff(u ? z(x, y - 1) : 0, zp, d ? z(x, y + 1) : 0, u, d);
                const float np[3] = {nrm(0, x, y), nrm(1, x, y), nrm(2, x, y)};
                const int32_t idp = ids ? ids[size_t(y) * size_t(w) + size_t(x)] : 0;
                float sw = 0, sc[3] = {0, 0, 0}, m1 = 0, m2 = 0;
                for (int j = -3; j <= 3; ++j) {
                    const int yq = y + j;
                    if (yq < 0 || yq >= h) continue;
                    for (int i = -3; i <= 3; ++i) {
                        const int xq = x + i;
                        if (xq < 0 || xq >= w) continue;
                        float wt = 1.f;  // the centre always counts fully
                        if (i != 0 || j != 0) {
                            if (ids && ids[size_t(yq) * size_t(w) + size_t(xq)] != idp) continue;
                            // Same edge-stopping functions as A-Trous (SVGF eq. 3-4), luminance
                            // on the raw difference (no variance yet: that is what we estimate).
                            const float ez = std::fabs(zp - z(xq, yq)) /
                                             (sigmaZ * std::fabs(gx * float(i) + gy * float(j)) +
                                              1e-5f * zp + 1e-8f);
                            const float el = std::fabs(lp - lum(xq, yq)) * invSigmaL;
                            float e = -(ez + el) * px::kLog2e;
                            if (sigmaN > 0.f) {
                                const float dot = np[0] * nrm(0, xq, yq) + np[1] * nrm(1, xq, yq) +
                                                  np[2] * nrm(2, xq, yq);
                                if (!(dot > 0.f)) continue;
                                e += sigmaN * px::fastLog2(std::min(std::max(dot, 1e-30f), 1.f));
                            }
                            wt = px::fastExp2(e);
                        }
                        sw += wt;
                        for (int c = 0; c < 3; ++c) sc[c] += wt * col(c, xq, yq);
                        m1 += wt * px::sanitize(moments.at(0, xq, yq));
                        m2 += wt * px::sanitizePositive(moments.at(1, xq, yq), 1e32f);
                    }
                }
                const float inv = 1.f / sw;  // sw >= 1 (centre)
                for (int c = 0; c < 3; ++c) outC.at(c, x, y) = sc[c] * inv;
                m1 *= inv;
                m2 *= inv;
                // Boost: few samples underestimate the variance (Falcor: 4 / historyLength).
                const float boost = 4.f / std::max(hl, 1.f);
                if (outV) outV->at(0, x, y) = std::max(0.f, m2 - m1 * m1) * boost;
            }
    });
}
