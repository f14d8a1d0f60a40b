#pragma once
// Plain scalar reference of the TemporalAccumulation pass: the straightforward per-pixel form
// (ImageView::at() reads sanitised where they are used, the firefly clamp's 8-neighbourhood
// with bounds checks, branches where the formula has them), kept to check the optimised pass
// against. Every floating-point operation is spelled out, fused multiply-adds included
// (std::fma where the pass's arithmetic fuses), and the test is compiled with
// -ffp-contract=off like the pass, so the two agree bit for bit.
#include <kestrel/Image.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace taccref {

using namespace kestrel;

struct Params {
    float alpha = 0.2f, momentsAlpha = 0.2f, maxHistoryLength = 32.f, fireflySigma = 3.f;
};

struct Outputs {
    Image color, moments, historyLength, variance;
};

/// Luminance of the sanitised colour: products rounded, summed left to right; in frames
/// narrower than 4 pixels the first product is fused into the first sum (how the pass has been
/// compiled: its vectorised luminance loop and its scalar fallback for short rows differ).
inline float luminance(float r, float g, float b, bool narrow) {
    r = px::sanitize(r), g = px::sanitize(g), b = px::sanitize(b);
    if (narrow) return std::fma(0.2126f, r, 0.7152f * g) + 0.0722f * b;
    return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}

/// prevColor / prevMoments / prevHistoryLength: null when not fed (the pass ignores colour and
/// moments without a history length).
inline Outputs accumulate(const Image& color, const Image* prevColor, const Image* prevMoments,
                          const Image* prevLength, const Params& p) {
    const int w = color.width(), h = color.height();
    Outputs out{Image(w, h, Format::Float3), Image(w, h, Format::Float2),
                Image(w, h, Format::Float), Image(w, h, Format::Float)};
    if (!prevLength) prevColor = prevMoments = nullptr;
    auto lum = [&](int x, int y) {
        return luminance(color.at(0, x, y), color.at(1, x, y), color.at(2, x, y), w < 4);
    };
    const float k = p.fireflySigma, cap = p.maxHistoryLength;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float c[3] = {px::sanitize(color.at(0, x, y)), px::sanitize(color.at(1, x, y)),
                          px::sanitize(color.at(2, x, y))};
            float l = lum(x, y);
            const float hPrev =
                prevLength ? px::sanitizePositive(prevLength->at(0, x, y), 1e6f) : 0.f;
            const bool valid = hPrev > 0.f;
            float m1p = 0.f, m2p = 0.f;
            if (valid && prevMoments) {
                m1p = px::sanitize(prevMoments->at(0, x, y));
                m2p = px::sanitizePositive(prevMoments->at(1, x, y), 1e32f);
            }
            const float hl = valid ? std::min(cap, hPrev + 1.f) : 1.f;
            const float ac = std::max(p.alpha, 1.f / hl), am = std::max(p.momentsAlpha, 1.f / hl);
            // k over the weight the sample enters the colour with (1 without a colour history).
            const float ke = k / (valid && prevColor ? ac : 1.f);
            if (k > 0.f && l > 0.f) {
                // Statistics of the 8 neighbours (the centre excluded), row by row.
                float s1 = 0.f, s2 = 0.f;
                int n = 0;
                for (int j = -1; j <= 1; ++j)
                    for (int i = -1; i <= 1; ++i) {
                        const int xx = x + i, yy = y + j;
                        if ((i == 0 && j == 0) || xx < 0 || xx >= w || yy < 0 || yy >= h) continue;
                        const float q = lum(xx, yy);
                        s1 += q;
                        s2 = std::fma(q, q, s2);
                        ++n;
                    }
                float bound = 1e30f;
                if (n > 0) {
                    const float mu = s1 / float(n);
                    bound = std::fma(std::sqrt(std::max(0.f, std::fma(-mu, mu, s2 / float(n)))), ke,
                                     mu);
                }
                if (valid && prevMoments)
                    bound = std::max(
                        bound,
                        std::fma(std::sqrt(std::max(0.f, std::fma(-m1p, m1p, m2p))), ke, m1p));
                if (l > bound) {
                    const float s = std::max(bound, 0.f) / l;
                    for (float& v : c) v *= s;
                    // The moments take l - b, held to [b, 2b], so a recurring sample passes.
                    const float b = std::max(bound, 0.f);
                    l = std::min(std::max(l - b, b), 2.f * b);
                }
            }
            if (k > 0.f && l < 0.f && valid && prevMoments) {
                // A negative sample below the history's mean - k' sigma is held to it (<= 0).
                const float sh = std::sqrt(std::max(0.f, std::fma(-m1p, m1p, m2p)));
                const float low = std::min(std::fma(-ke, sh, m1p), 0.f);
                if (l < low) {
                    for (float& v : c) v *= low / l;
                    l = low;
                }
            }
            for (int ch = 0; ch < 3; ++ch) {
                float v = c[ch];
                if (valid && prevColor) {
                    const float q = px::sanitize(prevColor->at(ch, x, y));
                    v = std::fma(ac, v - q, q);
                }
                out.color.at(ch, x, y) = v;
            }
            float m1 = l, m2 = l * l;
            if (valid && prevMoments) {
                m1 = std::fma(am, m1 - m1p, m1p);
                m2 = std::fma(am, m2 - m2p, m2p);
            }
            out.moments.at(0, x, y) = m1;
            out.moments.at(1, x, y) = m2;
            out.historyLength.at(0, x, y) = hl;
            out.variance.at(0, x, y) = std::max(0.f, std::fma(-m1, m1, m2));
        }
    return out;
}

}  // namespace taccref
