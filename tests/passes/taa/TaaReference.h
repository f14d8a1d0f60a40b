#pragma once
// Plain scalar reference of the TAA pass: the straightforward per-pixel form (3x3 window
// clamped at the border, the current frame converted to YCoCg where it is read, branches where
// the formula has them), kept to check the optimised pass against. Every floating-point
// operation is spelled out, fused multiply-adds included (std::fma exactly where the compiler
// used to contract the pass's expressions), and the test is compiled with -ffp-contract=off like
// the pass, so the two agree bit for bit whatever the compiler would contract.
#include <kestrel/Image.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace taaref {

using namespace kestrel;

struct Params {
    float alpha = 0.1f, gamma = 1.f;
    bool clip = true, antiFlicker = true;
    float blurAlpha = 1.f;  ///< alpha where resampleBlur is 1
    bool warmUp = false;    ///< len is TAA's own age: the current weight is >= 2 / (len + 2)
};

inline float sanitise(float v) {
    constexpr float kMaxValue = 1e18f;
    return v == v ? std::clamp(v, -kMaxValue, kMaxValue) : 0.f;
}

/// history / historyLength / blur (resampleBlur): null when not bound. Returns the Float3 output;
/// age (if given, Float): the historyLength output, len + 1 (at most 255) where the history is
/// used, else 1.
inline Image taa(const Image& cur, const Image* hist, const Image* len, const Params& p,
                 const Image* blur = nullptr, Image* age = nullptr) {
    const int w = cur.width(), h = cur.height();
    Image out(w, h, Format::Float3);
    if (age) *age = Image(w, h, Format::Float);
    auto ycc = [&](int x, int y, float v[3]) {
        const float r = sanitise(cur.at(0, x, y)), g = sanitise(cur.at(1, x, y)),
                    b = sanitise(cur.at(2, x, y));
        v[0] = 0.25f * r + 0.5f * g + 0.25f * b;
        v[1] = 0.5f * r - 0.5f * b;
        v[2] = 0.5f * g - 0.25f * r - 0.25f * b;  // -0.25 r + 0.5 g - 0.25 b
    };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            bool valid = hist && (!len || len->at(0, x, y) > 0.f);
            if (valid)
                for (int ch = 0; ch < 3; ++ch) valid = valid && std::isfinite(hist->at(ch, x, y));
            const float l = len ? len->at(0, x, y) : 1.f;
            if (age) age->at(0, x, y) = valid ? std::min(l + 1.f, 255.f) : 1.f;
            if (!valid) {  // no history or disoccluded: exactly the current colour
                for (int ch = 0; ch < 3; ++ch) out.at(ch, x, y) = sanitise(cur.at(ch, x, y));
                continue;
            }
            float c[3];
            ycc(x, y, c);
            const float hr = sanitise(hist->at(0, x, y)), hg = sanitise(hist->at(1, x, y)),
                        hb = sanitise(hist->at(2, x, y));
            float hv[3] = {0.25f * hr + 0.5f * hg + 0.25f * hb, 0.5f * hr - 0.5f * hb,
                           0.5f * hg - 0.25f * hr - 0.25f * hb};
            // 3x3 mean and standard deviation, shifted by the centre.
            const int ya = std::max(0, y - 1), yb = std::min(h - 1, y + 1);
            const int xa = std::max(0, x - 1), xb = std::min(w - 1, x + 1);
            const bool interior = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
            const float n = float((yb - ya + 1) * (xb - xa + 1));
            float s1[3] = {0, 0, 0}, s2[3] = {0, 0, 0};
            for (int yy = ya; yy <= yb; ++yy)
                for (int xx = xa; xx <= xb; ++xx) {
                    float q[3];
                    ycc(xx, yy, q);
                    for (int ch = 0; ch < 3; ++ch) {
                        const float d = q[ch] - c[ch];
                        s1[ch] += d;
                        // Squares summed with FMAs, except Y and Co of pixels with a full
                        // 3x3 window (rounded products: how the pass has been compiled).
                        s2[ch] = interior && ch < 2 ? s2[ch] + d * d : std::fma(d, d, s2[ch]);
                    }
                }
            float mu[3], lo[3], hi[3];
            for (int ch = 0; ch < 3; ++ch) {
                const float m1 = s1[ch] / n;
                const float ext = p.gamma * std::sqrt(std::max(0.f, std::fma(-m1, m1, s2[ch] / n)));
                mu[ch] = c[ch] + m1;
                lo[ch] = std::min(mu[ch] - ext, c[ch]);
                hi[ch] = std::max(mu[ch] + ext, c[ch]);
            }
            if (p.clip) {
                float t = 1.f;
                for (int ch = 0; ch < 3; ++ch) {
                    const float off = hv[ch] - mu[ch];
                    if (hv[ch] > hi[ch]) t = std::min(t, (hi[ch] - mu[ch]) / off);
                    if (hv[ch] < lo[ch]) t = std::min(t, (lo[ch] - mu[ch]) / off);
                }
                for (int ch = 0; ch < 3; ++ch) hv[ch] = std::fma(hv[ch] - mu[ch], t, mu[ch]);
            } else {
                for (int ch = 0; ch < 3; ++ch) hv[ch] = std::clamp(hv[ch], lo[ch], hi[ch]);
            }
            float b = blur ? blur->at(0, x, y) : 0.f;
            b = b > 0.f ? std::min(b, 1.f) : 0.f;  // NaN counts as 0
            float alpha = std::fma(b, p.blurAlpha - p.alpha, p.alpha);
            if (p.warmUp && len) alpha = std::max(alpha, 2.f / (std::max(l, 0.f) + 2.f));
            float wc = alpha, wh = 1.f - alpha;
            if (p.antiFlicker) {
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
            float res[3];
            // The blend's multiply-add is fused on the history term for pixels with a full 3x3
            // window and on the current term at the image border (how the pass has always
            // been compiled: its two code paths were contracted differently).
            for (int ch = 0; ch < 3; ++ch)
                res[ch] =
                    interior ? std::fma(wh, hv[ch], wc * c[ch]) : std::fma(wc, c[ch], wh * hv[ch]);
            out.at(0, x, y) = res[0] + res[1] - res[2];
            out.at(1, x, y) = res[0] + res[2];
            out.at(2, x, y) = res[0] - res[1] - res[2];
        }
    return out;
}

}  // namespace taaref
