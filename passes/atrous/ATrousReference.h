#pragma once
// The plain path of one A-Trous iteration (SVGF eq. 1-5, section 4.4): scalar, pixel by pixel,
// libm's exp and pow, no precomputation. The equivalence tests hold the vectorised pass to it
// (tests/passes/atrous), and the pass runs it when its `exact` parameter is set, so that
// `kestrel bench` can put the fast path's error next to the plain path's.
#include <kestrel/Image.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "ATrousPass.h"

namespace kestrel::reference {

struct ATrousInputs {
    const ImageView *color, *var, *depth, *normal, *ids;  ///< var and ids may be null
    // The pass's defaults.
    int step = ATrousPass::Params{}.step;
    float sigmaZ = ATrousPass::Params{}.sigmaZ, sigmaN = ATrousPass::Params{}.sigmaN;
    float sigmaL = ATrousPass::Params{}.sigmaL, sigmaColor = ATrousPass::Params{}.sigmaColor;
    float depthPrecision = 0.f;  ///< relative step r of the stored depth (0: float)
};

/// Rows [y0, y1) of the output (outVar may be null).
inline void atrous(const ATrousInputs& in, const ImageView& outColor, const ImageView* outVar,
                   int y0, int y1) {
    const int w = in.color->width(), h = in.color->height();
    auto col = [&](int c, int x, int y) { return px::sanitize(in.color->at(c, x, y)); };
    auto lum = [&](int x, int y) {
        return px::luminance(col(0, x, y), col(1, x, y), col(2, x, y));
    };
    auto z = [&](int x, int y) { return px::sanitizeDepth(in.depth->at(0, x, y)); };
    auto nrm = [&](int c, int x, int y) { return px::sanitizeNormal(in.normal->at(c, x, y)); };
    auto var = [&](int x, int y) {
        return in.var ? px::sanitizePositive(in.var->at(0, x, y), 1e32f) : 0.f;
    };
    const float kh[5] = {1.f / 16, 1.f / 4, 3.f / 8, 1.f / 4, 1.f / 16};
    for (int y = y0; y < y1; ++y)
        for (int x = 0; x < w; ++x) {
            // 3x3 Gaussian of the variance, renormalised at the border (section 4.4).
            float gv = 0, gw = 0;
            for (int j = -1; j <= 1; ++j)
                for (int i = -1; i <= 1; ++i) {
                    if (x + i < 0 || x + i >= w || y + j < 0 || y + j >= h) continue;
                    const float g = (i == 0 ? 0.5f : 0.25f) * (j == 0 ? 0.5f : 0.25f);
                    gv += g * var(x + i, y + j);
                    gw += g;
                }
            const float sigmaLum =
                in.var ? in.sigmaL * std::sqrt(gv / gw) + 1e-10f : in.sigmaColor + 1e-10f;
            const bool l = x > 0, r = x + 1 < w, u = y > 0, d = y + 1 < h;
            const float zp = z(x, y), lp = lum(x, y);
            const float gx = px::minAbsDiff(l ? z(x - 1, y) : 0, zp, r ? z(x + 1, y) : 0, l, r);
            const float gy = px::minAbsDiff(u ? z(x, y - 1) : 0, zp, d ? z(x, y + 1) : 0, u, d);
            float sw = 0, sc[3] = {0, 0, 0}, sv = 0;
            for (int j = -2; j <= 2; ++j)
                for (int i = -2; i <= 2; ++i) {
                    const int dx = i * in.step, dy = j * in.step, xq = x + dx, yq = y + dy;
                    if (xq < 0 || xq >= w || yq < 0 || yq >= h) continue;
                    float wt = kh[i + 2] * kh[j + 2];
                    if (i != 0 || j != 0) {
                        if (in.ids && in.ids->atInt(xq, yq) != in.ids->atInt(x, y)) continue;
                        const float dot = nrm(0, x, y) * nrm(0, xq, yq) +
                                          nrm(1, x, y) * nrm(1, xq, yq) +
                                          nrm(2, x, y) * nrm(2, xq, yq);
                        if (in.sigmaN > 0.f && !(dot > 0.f)) continue;
                        const float wn =
                            in.sigmaN > 0.f ? std::pow(std::min(dot, 1.f), in.sigmaN) : 1.f;
                        // Quantised depth (r z steps) misestimates the slope by up to r z per
                        // pixel and each depth by r z: the tolerance grows by both.
                        const float qz = in.depthPrecision * zp;
                        const float ez = std::fabs(zp - z(xq, yq)) /
                                         (in.sigmaZ * (std::fabs(gx * float(dx) + gy * float(dy)) +
                                                       qz * float(std::abs(dx) + std::abs(dy))) +
                                          (1e-5f + in.depthPrecision) * zp + 1e-8f);
                        const float el = std::fabs(lp - lum(xq, yq)) / sigmaLum;
                        wt *= std::exp(-(ez + el)) * wn;
                    }
                    sw += wt;
                    for (int c = 0; c < 3; ++c) sc[c] += wt * col(c, xq, yq);
                    sv += wt * wt * var(xq, yq);
                }
            for (int c = 0; c < 3; ++c) outColor.at(c, x, y) = sc[c] / sw;
            if (outVar) outVar->at(0, x, y) = sv / (sw * sw);
        }
}

}  // namespace kestrel::reference
