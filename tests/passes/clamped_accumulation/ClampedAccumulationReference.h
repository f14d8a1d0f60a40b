#pragma once
// Plain scalar reference of the ClampedAccumulation pass: the straightforward per-pixel form
// ((2 radius + 1)^2 window clipped at the border, ImageView::at() reads sanitised where they
// are used, branches where the formula has them), kept to check the optimised pass against.
// Every floating-point operation is spelled out, fused multiply-adds included (std::fma where
// the pass's arithmetic fuses), and the test is compiled with -ffp-contract=off like the
// pass, so the two agree bit for bit.
#include <kestrel/Image.h>

#include <algorithm>
#include <cmath>

namespace clampref {

using namespace kestrel;

struct Params {
    float alpha = 0.2f, k = 1.f;
    bool holdCurrent = false;
    int radius = 3;
};

inline float sanitise(float v) {
    constexpr float kMaxValue = 1e18f;
    return v == v ? std::clamp(v, -kMaxValue, kMaxValue) : 0.f;
}

/// history / historyLength: null when not bound.
inline Image accumulate(const Image& cur, const Image* hist, const Image* len, const Params& p) {
    const int w = cur.width(), h = cur.height(), r = p.radius;
    Image out(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            bool valid = hist && (!len || len->at(0, x, y) > 0.f);  // NaN length: invalid
            for (int c = 0; c < 3 && valid; ++c) valid = std::isfinite(hist->at(c, x, y));
            for (int c = 0; c < 3; ++c) {
                const float centre = sanitise(cur.at(c, x, y));
                if (!valid) {
                    out.at(c, x, y) = centre;
                    continue;
                }
                // Window sums of (C_q - C_p) and its square, row by row, left to right.
                float s1 = 0, s2 = 0, n = 0;
                for (int yy = std::max(0, y - r); yy <= std::min(h - 1, y + r); ++yy)
                    for (int xx = x - r; xx <= x + r; ++xx) {
                        if (xx < 0 || xx >= w) continue;
                        const float d = sanitise(cur.at(c, xx, yy)) - centre;
                        s1 += d;
                        s2 = std::fma(d, d, s2);
                        n += 1.f;
                    }
                const float inv = 1.f / n;
                const float m1 = s1 * inv;
                const float var = std::max(0.f, std::fma(s2, inv, -(m1 * m1)));
                const float mu = centre + m1, sigma = std::sqrt(var);
                float lo = std::fma(-p.k, sigma, mu), hi = std::fma(p.k, sigma, mu);
                if (p.holdCurrent) {
                    lo = std::min(lo, centre);
                    hi = std::max(hi, centre);
                }
                const float clamped = std::clamp(hist->at(c, x, y), lo, hi);
                out.at(c, x, y) = std::fma(p.alpha, centre, (1.f - p.alpha) * clamped);
            }
        }
    return out;
}

}  // namespace clampref
