#include "eval/Metrics.h"

#include <kestrel/Error.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <string>
#include <vector>

#include "display/ToneMap.h"

namespace kestrel::eval {
namespace {

constexpr int kRgb = 3;

void requireRgb(const ImageView& v, const char* what) {
    if (!v.valid() || v.channels() < kRgb || v.format == Format::Int32)
        throw Error(std::string(what) + ": expected an RGB float image (Float3 or Float4)");
}

void requireSameRgb(const ImageView& a, const ImageView& b) {
    requireRgb(a, "output");
    requireRgb(b, "reference");
    if (a.extent != b.extent)
        throw Error("image sizes differ: output " + std::to_string(a.width()) + "x" +
                    std::to_string(a.height()) + ", reference " + std::to_string(b.width()) + "x" +
                    std::to_string(b.height()));
}

std::string sizeText(const ImageView& v) {
    return std::to_string(v.width()) + "x" + std::to_string(v.height());
}

// ---- SSIM (Wang et al. 2004) ------------------------------------------------------------------

constexpr int kRadius = 5;  // 11x11 window
constexpr int kTaps = 2 * kRadius + 1;
constexpr double kSigma = 1.5;
constexpr float kC1 = 0.01f * 0.01f;  // (K1 L)^2
constexpr float kC2 = 0.03f * 0.03f;  // (K2 L)^2

struct Gaussian {
    float w[kTaps];
    Gaussian() {
        double sum = 0;
        double tmp[kTaps];
        for (int k = 0; k < kTaps; ++k) {
            const double d = k - kRadius;
            tmp[k] = std::exp(-d * d / (2 * kSigma * kSigma));
            sum += tmp[k];
        }
        for (int k = 0; k < kTaps; ++k) w[k] = float(tmp[k] / sum);
    }
};
const Gaussian kGauss;

// out[x] = sum_k g[k] in[x + k - R], over taps inside [0, n), divided by the sum of those taps'
// weights (truncated, renormalised window; identical to the plain sum in the interior).
void blurLine(const float* __restrict in, float* __restrict out, int n) {
    const int lo = std::min(kRadius, n), hi = std::max(lo, n - kRadius);
    for (int x = lo; x < hi; ++x) {
        float s = 0;
        for (int k = 0; k < kTaps; ++k) s += kGauss.w[k] * in[x + k - kRadius];
        out[x] = s;
    }
    auto edge = [&](int x) {
        float s = 0, ws = 0;
        for (int k = 0; k < kTaps; ++k) {
            const int i = x + k - kRadius;
            if (i < 0 || i >= n) continue;
            s += kGauss.w[k] * in[i];
            ws += kGauss.w[k];
        }
        out[x] = s / ws;  // ws >= the centre weight > 0
    };
    for (int x = 0; x < lo; ++x) edge(x);
    for (int x = hi; x < n; ++x) edge(x);
}

// Vertical blur of output row y: rows[k] is input row y + k - R (only k in the valid range is
// read); same renormalisation at the top and bottom border.
void blurColumnRow(const float* const* rows, float* __restrict out, int w, int h, int y) {
    if (y >= kRadius && y + kRadius < h) {
        for (int x = 0; x < w; ++x) {
            float s = 0;
            for (int k = 0; k < kTaps; ++k) s += kGauss.w[k] * rows[k][x];
            out[x] = s;
        }
        return;
    }
    const int k0 = std::max(0, kRadius - y), k1 = std::min(kTaps, h - y + kRadius);
    float ws = 0;
    for (int x = 0; x < w; ++x) out[x] = 0;
    for (int k = k0; k < k1; ++k) {
        const float g = kGauss.w[k];
        ws += g;
        for (int x = 0; x < w; ++x) out[x] += g * rows[k][x];
    }
    const float inv = 1.0f / ws;
    for (int x = 0; x < w; ++x) out[x] *= inv;
}

constexpr int kMoments = 5;  // x, y, x^2, y^2, xy (about the global means)

// Mean SSIM of one channel, streamed row by row: each input row's five local moments are blurred
// horizontally into a ring of the last 11 rows, and each output row is blurred vertically from
// that ring (separable Gaussian; the truncated window of a border pixel is the product of two
// truncated 1D windows, so renormalising each 1D pass is exact). The working set stays in cache.
// Second moments are taken about each image's global mean (cx, cy): variances and covariance do
// not change, and float cancellation in E[x^2] - mu^2 shrinks (exact for constant images).
double ssimPlane(const float* xs, const float* ys, int w, int h) {
    const size_t n = size_t(w) * size_t(h);
    double sx = 0, sy = 0;
    for (size_t i = 0; i < n; ++i) sx += xs[i], sy += ys[i];
    const float cx = float(sx / double(n)), cy = float(sy / double(n));

    const size_t W = size_t(w);
    std::vector<float> ring(size_t(kMoments) * kTaps * W);  // [moment][slot][x]
    auto slot = [&](int m, int row) { return ring.data() + (size_t(m) * kTaps + row % kTaps) * W; };
    std::vector<float> prod(kMoments * W), acc(kMoments * W);
    float *dx = prod.data(), *dy = dx + W, *xx = dy + W, *yy = xx + W, *xy = yy + W;
    const float *mx = acc.data(), *my = mx + W, *exx = my + W, *eyy = exx + W, *exy = eyy + W;
    double total = 0;
    for (int r = 0; r < h + kRadius; ++r) {
        if (r < h) {
            const float* xr = xs + size_t(r) * W;
            const float* yr = ys + size_t(r) * W;
            for (int x = 0; x < w; ++x) {
                dx[x] = xr[x] - cx;
                dy[x] = yr[x] - cy;
                xx[x] = dx[x] * dx[x];
                yy[x] = dy[x] * dy[x];
                xy[x] = dx[x] * dy[x];
            }
            for (int m = 0; m < kMoments; ++m) blurLine(prod.data() + size_t(m) * W, slot(m, r), w);
        }
        const int y = r - kRadius;
        if (y < 0) continue;
        for (int m = 0; m < kMoments; ++m) {
            const float* rows[kTaps] = {};
            for (int k = 0; k < kTaps; ++k) {
                const int src = y + k - kRadius;
                if (src >= 0 && src < h) rows[k] = slot(m, src);
            }
            blurColumnRow(rows, acc.data() + size_t(m) * W, w, h, y);
        }
        float rowSum = 0;
        for (int x = 0; x < w; ++x) {
            const float ux = mx[x] + cx, uy = my[x] + cy;
            const float sxx = exx[x] - mx[x] * mx[x];
            const float syy = eyy[x] - my[x] * my[x];
            const float sxy = exy[x] - mx[x] * my[x];
            // Wang et al. 2004, eq. 13.
            const float num = (2 * ux * uy + kC1) * (2 * sxy + kC2);
            const float den = (ux * ux + uy * uy + kC1) * (sxx + syy + kC2);
            rowSum += num / den;  // den >= C1 * (C2 - rounding) > 0 for values in [0, 1]
        }
        total += rowSum;
    }
    return total / double(n);
}

}  // namespace

std::string_view toneMapName(ToneMap t) {
    switch (t) {
        case ToneMap::Reinhard:
            return "reinhard";
        case ToneMap::Clamp:
            return "clamp";
        case ToneMap::Srgb:
            return "srgb";
    }
    return "?";
}

std::optional<ToneMap> parseToneMap(std::string_view name) {
    for (ToneMap t : {ToneMap::Reinhard, ToneMap::Clamp, ToneMap::Srgb})
        if (name == toneMapName(t)) return t;
    return std::nullopt;
}

float toneMap(ToneMap t, float x) {
    using display::ToneCurve;
    switch (t) {
        case ToneMap::Reinhard:
            // Saturating at 1e30, not at the previews' 1e6: between the two x / (1 + x) still
            // changes in float, and the metrics' figures were computed without that limit.
            return display::gamma22Encode(display::toneMap(x, ToneCurve::Reinhard, 1e30f));
        case ToneMap::Clamp:
            return display::toneMap(x, ToneCurve::Clamp);
        case ToneMap::Srgb:
            return display::srgbEncode(display::toneMap(x, ToneCurve::Clamp));
    }
    return 0;
}

Image sanitizedRgb(const ImageView& image, size_t* nonFinite, const char* what) {
    requireRgb(image, what);
    Image out(image.extent, Format::Float3);
    const size_t n = image.pixels();
    std::vector<unsigned char> bad(n, 0);
    for (int c = 0; c < kRgb; ++c) {
        const float* src = image.channel(c);
        float* dst = out.channel(c);
        for (size_t i = 0; i < n; ++i) {
            const float v = src[i];
            if (std::isfinite(v)) {
                dst[i] = v;
            } else {
                bad[i] = 1;
                dst[i] = std::isnan(v) ? 0.0f : (v > 0 ? FLT_MAX : -FLT_MAX);
            }
        }
    }
    if (nonFinite) {
        size_t count = 0;
        for (unsigned char b : bad) count += b;
        *nonFinite = count;
    }
    return out;
}

Image toneMapped(const ImageView& rgb, ToneMap t) {
    requireRgb(rgb, "image");
    Image out(rgb.extent, Format::Float3);
    const size_t n = rgb.pixels();
    for (int c = 0; c < kRgb; ++c) {
        const float* src = rgb.channel(c);
        float* dst = out.channel(c);
        for (size_t i = 0; i < n; ++i) dst[i] = toneMap(t, src[i]);
    }
    return out;
}

double relMse(const ImageView& out, const ImageView& ref) {
    requireSameRgb(out, ref);
    const size_t n = out.pixels();
    double total = 0;
    for (int c = 0; c < kRgb; ++c) {
        const float *o = out.channel(c), *r = ref.channel(c);
        for (size_t i = 0; i < n; ++i) {
            // docs/design.md section 7; in double so that FLT_MAX (a sanitised Inf) stays finite.
            const double d = double(o[i]) - double(r[i]);
            total += d * d / (double(r[i]) * double(r[i]) + 1e-2);
        }
    }
    return n ? total / double(n * kRgb) : 0.0;
}

double psnr(const ImageView& outDisplay, const ImageView& refDisplay) {
    requireSameRgb(outDisplay, refDisplay);
    const size_t n = outDisplay.pixels();
    double total = 0;
    for (int c = 0; c < kRgb; ++c) {
        const float *o = outDisplay.channel(c), *r = refDisplay.channel(c);
        for (size_t i = 0; i < n; ++i) {
            const double d = double(o[i]) - double(r[i]);
            total += d * d;
        }
    }
    const double mse = std::max(n ? total / double(n * kRgb) : 0.0, 1e-10);
    return 10.0 * std::log10(1.0 / mse);  // peak 1
}

double ssim(const ImageView& outDisplay, const ImageView& refDisplay) {
    requireSameRgb(outDisplay, refDisplay);
    if (outDisplay.pixels() == 0) return 1.0;
    double sum = 0;
    for (int c = 0; c < kRgb; ++c)
        sum += ssimPlane(outDisplay.channel(c), refDisplay.channel(c), outDisplay.width(),
                         outDisplay.height());
    return sum / kRgb;
}

double temporalInstability(const ImageView& out, const ImageView& outPrev, const ImageView& ref,
                           const ImageView& refPrev) {
    requireSameRgb(out, ref);
    requireSameRgb(outPrev, refPrev);
    if (out.extent != outPrev.extent)
        throw Error("frame size changed within the sequence: " + sizeText(outPrev) + " then " +
                    sizeText(out));
    const size_t n = out.pixels();
    double total = 0;
    for (int c = 0; c < kRgb; ++c) {
        const float *o = out.channel(c), *op = outPrev.channel(c);
        const float *r = ref.channel(c), *rp = refPrev.channel(c);
        for (size_t i = 0; i < n; ++i) total += temporalError(o[i], op[i], r[i], rp[i]);
    }
    return n ? total / double(n * kRgb) : 0.0;
}

// ---- Speckles ---------------------------------------------------------------------------------

namespace {
// Rec. 709 luminance of pixel i, negatives as 0 (a speckle is dark, not negative).
std::vector<float> luminancePlane(const ImageView& v) {
    const size_t n = v.pixels();
    std::vector<float> l(n);
    const float *r = v.channel(0), *g = v.channel(1), *b = v.channel(2);
    for (size_t i = 0; i < n; ++i)
        l[i] = std::max(0.f, 0.2126f * r[i] + 0.7152f * g[i] + 0.0722f * b[i]);
    return l;
}

float median3x3(const std::vector<float>& l, int w, int h, int x, int y) {
    float v[9];
    int k = 0;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            const int xx = std::clamp(x + dx, 0, w - 1), yy = std::clamp(y + dy, 0, h - 1);
            v[k++] = l[size_t(yy) * size_t(w) + size_t(xx)];
        }
    std::nth_element(v, v + 4, v + 9);
    return v[4];
}
}  // namespace

std::vector<uint8_t> speckleMask(const ImageView& out, const ImageView& ref) {
    requireSameRgb(out, ref);
    const int w = out.width(), h = out.height();
    const std::vector<float> lo = luminancePlane(out), lr = luminancePlane(ref);
    double sum = 0;
    for (float v : lr) sum += v;
    const float notDark = float(0.05 * sum / double(std::max<size_t>(lr.size(), 1)));
    std::vector<uint8_t> mask(lo.size(), 0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            if (lr[i] > notDark && lo[i] < 0.3f * lr[i] && median3x3(lo, w, h, x, y) > 2.f * lo[i])
                mask[i] = 1;
        }
    return mask;
}

double specklesPerMegapixel(const std::vector<uint8_t>& mask) {
    size_t count = 0;
    for (uint8_t m : mask) count += m;
    return mask.empty() ? 0.0 : 1e6 * double(count) / double(mask.size());
}

FrameMetrics compareImages(const ImageView& out, const ImageView& ref, ToneMap tm,
                           const FrameImages* previous, FrameImages* current) {
    requireSameRgb(out, ref);
    FrameMetrics m;
    Image o = sanitizedRgb(out, &m.nonFiniteOutput, "output");
    Image r = sanitizedRgb(ref, &m.nonFiniteReference, "reference");
    m.relMse = relMse(o, r);
    m.speckles = specklesPerMegapixel(speckleMask(o, r));
    FrameImages display{toneMapped(o, tm), toneMapped(r, tm)};
    m.psnr = psnr(display.outDisplay, display.refDisplay);
    m.ssim = ssim(display.outDisplay, display.refDisplay);
    if (previous && previous->outDisplay.extent().pixels() > 0)
        m.temporal = temporalInstability(display.outDisplay, previous->outDisplay,
                                         display.refDisplay, previous->refDisplay);
    if (current) *current = std::move(display);
    return m;
}

}  // namespace kestrel::eval
