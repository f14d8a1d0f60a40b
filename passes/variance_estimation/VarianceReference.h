#pragma once
// The plain path of VarianceEstimation (SVGF section 4.2): scalar, pixel by pixel, libm's exp
// and pow. The equivalence tests hold the vectorised pass to it, and the pass runs it when its
// `exact` parameter is set (for the fast-versus-plain rows of `kestrel bench`).
#include <kestrel/Image.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>

#include "VarianceEstimationPass.h"

namespace kestrel::reference {

/// The smallest luminance tolerance VarianceEstimation uses (a smaller sigmaL counts as this).
constexpr float kMinSigmaL = 1e-6f;

struct VarianceInputs {
    const ImageView *color, *moments, *length, *var, *depth, *normal, *ids;  ///< ids may be null
    // The pass's defaults (sigmaL 0: none).
    float sigmaZ = VarianceEstimationPass::Params{}.sigmaZ;
    float sigmaN = VarianceEstimationPass::Params{}.sigmaN;
    float sigmaL = VarianceEstimationPass::Params{}.sigmaL;
    float minHistory = VarianceEstimationPass::Params{}.minHistoryLength;
};

/// Rows [y0, y1) of the output (outVar may be null).
inline void varianceEstimation(const VarianceInputs& in, const ImageView& outColor,
                               const ImageView* outVar, int y0, int y1) {
    const int w = in.color->width(), h = in.color->height();
    auto col = [&](int c, int x, int y) { return px::sanitize(in.color->at(c, x, y)); };
    auto lum = [&](int x, int y) {
        return px::luminance(col(0, x, y), col(1, x, y), col(2, x, y));
    };
    auto z = [&](int x, int y) { return px::sanitizeDepth(in.depth->at(0, x, y)); };
    auto nrm = [&](int c, int x, int y) { return px::sanitizeNormal(in.normal->at(c, x, y)); };
    for (int y = y0; y < y1; ++y)
        for (int x = 0; x < w; ++x) {
            const float hl = px::sanitizePositive(in.length->at(0, x, y), 1e6f);
            if (hl >= in.minHistory) {
                for (int c = 0; c < 3; ++c) outColor.at(c, x, y) = col(c, x, y);
                if (outVar) outVar->at(0, x, y) = px::sanitizePositive(in.var->at(0, x, y), 1e32f);
                continue;
            }
            const bool l = x > 0, r = x + 1 < w, u = y > 0, d = y + 1 < h;
            const float zp = z(x, y), lp = lum(x, y);
            const float gx = px::minAbsDiff(l ? z(x - 1, y) : 0, zp, r ? z(x + 1, y) : 0, l, r);
            const float gy = px::minAbsDiff(u ? z(x, y - 1) : 0, zp, d ? z(x, y + 1) : 0, u, d);
            const int idp = in.ids ? in.ids->atInt(x, y) : 0;
            float sw = 0, sc[3] = {0, 0, 0}, m1 = 0, m2 = 0;
            for (int j = -3; j <= 3; ++j)
                for (int i = -3; i <= 3; ++i) {
                    const int xq = x + i, yq = y + j;
                    if (xq < 0 || xq >= w || yq < 0 || yq >= h) continue;
                    float wt = 1.f;
                    if (i != 0 || j != 0) {
                        if (in.ids && in.ids->atInt(xq, yq) != idp) continue;
                        // SVGF eq. 3 (depth), eq. 4 (normal), luminance with the fixed sigmaL
                        // (absolute units; 0: no luminance term).
                        const float ez = std::fabs(zp - z(xq, yq)) /
                                         (in.sigmaZ * std::fabs(gx * float(i) + gy * float(j)) +
                                          1e-5f * zp + 1e-8f);
                        const float el = in.sigmaL > 0.f ? std::fabs(lp - lum(xq, yq)) /
                                                               std::max(in.sigmaL, kMinSigmaL)
                                                         : 0.f;
                        float wn = 1.f;
                        if (in.sigmaN > 0.f) {
                            const float dot = nrm(0, x, y) * nrm(0, xq, yq) +
                                              nrm(1, x, y) * nrm(1, xq, yq) +
                                              nrm(2, x, y) * nrm(2, xq, yq);
                            if (!(dot > 0.f)) continue;
                            wn = std::pow(std::min(std::max(dot, 1e-30f), 1.f), in.sigmaN);
                        }
                        wt = std::exp(-(ez + el)) * wn;
                    }
                    sw += wt;
                    for (int c = 0; c < 3; ++c) sc[c] += wt * col(c, xq, yq);
                    m1 += wt * px::sanitize(in.moments->at(0, xq, yq));
                    m2 += wt * px::sanitizePositive(in.moments->at(1, xq, yq), 1e32f);
                }
            for (int c = 0; c < 3; ++c) outColor.at(c, x, y) = sc[c] / sw;
            m1 /= sw;
            m2 /= sw;
            if (outVar) outVar->at(0, x, y) = std::max(0.f, m2 - m1 * m1) * 4.f / std::max(hl, 1.f);
        }
}

}  // namespace kestrel::reference
