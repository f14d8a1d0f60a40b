#include "DepthChangeModel.h"

#include <kestrel/Conventions.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace kestrel {
namespace {

// One correspondence: normalised position, this frame's depth, last frame's depth where the
// motion vector lands, and the depth test's tolerance there (threshold * (fwidth + ...)).
struct Sample {
    double u, v, z, zPrev, tol;
};

using Params = std::array<double, 4>;  // a, b, c - 1, d: the change from the identity

double predict(const Params& p, const Sample& s) {
    return s.z * (p[0] * s.u + p[1] * s.v + 1.0 + p[2]) + p[3];
}

// Test error of a sample: |z_prev - predicted| in units of the tolerance (passes at <= 1).
double testError(const Params& p, const Sample& s) {
    return std::fabs(s.zPrev - predict(p, s)) / s.tol;
}

// Weighted least squares over the samples with keep[i]: minimises sum ((z_prev - prediction) /
// tol)^2, a small ridge toward the identity so that a degenerate set (one fronto-parallel plane:
// the z and 1 columns coincide up to scale) takes the solution nearest the identity.
bool solve(const std::vector<Sample>& samples, const std::vector<char>& keep, Params& out) {
    double m[4][5] = {};
    for (size_t i = 0; i < samples.size(); ++i) {
        if (!keep[i]) continue;
        const Sample& s = samples[i];
        const double f[4] = {s.z * s.u, s.z * s.v, s.z, 1.0};
        const double r = s.zPrev - s.z, wgt = 1.0 / (s.tol * s.tol);
        for (int j = 0; j < 4; ++j) {
            for (int k = 0; k < 4; ++k) m[j][k] += wgt * f[j] * f[k];
            m[j][4] += wgt * f[j] * r;
        }
    }
    for (int j = 0; j < 4; ++j) m[j][j] += 1e-9 * (m[j][j] + 1.0);
    for (int col = 0; col < 4; ++col) {  // Gaussian elimination, partial pivoting
        int piv = col;
        for (int r = col + 1; r < 4; ++r)
            if (std::fabs(m[r][col]) > std::fabs(m[piv][col])) piv = r;
        if (!(std::fabs(m[piv][col]) > 1e-300)) return false;
        for (int k = 0; k < 5; ++k) std::swap(m[col][k], m[piv][k]);
        for (int r = 0; r < 4; ++r) {
            if (r == col) continue;
            const double f = m[r][col] / m[col][col];
            for (int k = col; k < 5; ++k) m[r][k] -= f * m[col][k];
        }
    }
    for (int j = 0; j < 4; ++j) {
        out[size_t(j)] = m[j][4] / m[j][j];
        if (!std::isfinite(out[size_t(j)])) return false;
    }
    return true;
}

std::vector<Sample> gatherSamples(const DepthChangeInputs& in, const DepthChangeModel& frame) {
    const int w = in.width, h = in.height;
    std::vector<Sample> samples;
    if (w < 3 || h < 3) return samples;
    // A regular grid of at most about 16k interior pixels (each needs its four neighbours).
    const int stride = std::max(1, int(std::sqrt(double(w) * double(h) / 16384.0)));
    auto z = [&](int x, int y) { return px::sanitizeDepth(in.depth[size_t(y) * size_t(w) + x]); };
    for (int y = 1; y + 1 < h; y += stride)
        for (int x = 1; x + 1 < w; x += stride) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            const float zc = z(x, y);
            if (!(zc > 0.f && zc < kBackgroundDepth)) continue;
            const float px = float(x) + 0.5f + in.motionX[i], py = float(y) + 0.5f + in.motionY[i];
            if (!(std::fabs(px) < 1e7f && std::fabs(py) < 1e7f)) continue;  // also NaN
            const int tx = int(std::floor(px)), ty = int(std::floor(py));
            if (tx < 0 || ty < 0 || tx >= w || ty >= h) continue;
            const size_t t = size_t(ty) * size_t(w) + size_t(tx);
            if (in.ids && in.prevIds && in.ids[i] != in.prevIds[t]) continue;
            const float zp = px::sanitizeDepth(in.prevDepth[t]);
            if (!(zp > 0.f && zp < kBackgroundDepth)) continue;
            // The pass's tolerance (ReprojectionPass derivativesAt): fwidth from the smaller
            // one-sided differences, the stored depth's step, 0.01.
            const float fw = std::fabs(px::minAbsDiff(z(x - 1, y), zc, z(x + 1, y), true, true)) +
                             std::fabs(px::minAbsDiff(z(x, y - 1), zc, z(x, y + 1), true, true));
            const double tol =
                double(in.depthThreshold) * (double(fw) + 2.0 * in.depthStep * zc + 1e-2);
            if (!(tol > 0.0 && std::isfinite(tol))) continue;
            samples.push_back({frame.u(x), frame.v(y), zc, zp, tol});
        }
    return samples;
}

}  // namespace

DepthChangeModel fitDepthChange(const DepthChangeInputs& in) {
    DepthChangeModel model;
    const int w = in.width, h = in.height;
    if (w <= 0 || h <= 0) return model;
    model.uScale = 1.f / float(std::max(w, h));
    model.uOffset = 0.5f - 0.5f * float(w);
    model.vOffset = 0.5f - 0.5f * float(h);
    if (!in.depth || !in.prevDepth || !in.motionX || !in.motionY) return model;
    const std::vector<Sample> samples = gatherSamples(in, model);
    constexpr size_t kMinSamples = 64;
    if (samples.size() < kMinSamples) return model;

    const Params identity{0, 0, 0, 0};
    auto passing = [&](const Params& p) {
        size_t n = 0;
        for (const Sample& s : samples) n += testError(p, s) <= 1.0;
        return n;
    };
    // Trimmed least squares: fit, keep the samples within max(1, 3 x the median test error)
    // (moving objects and disocclusions are outliers), refit; the bound reaches the test itself
    // once most samples pass.
    std::vector<char> keep(samples.size(), 1);
    std::vector<double> err(samples.size());
    Params p = identity;
    for (int iter = 0; iter < 8; ++iter) {
        Params next;
        if (!solve(samples, keep, next)) break;
        p = next;
        for (size_t i = 0; i < samples.size(); ++i) err[i] = testError(p, samples[i]);
        std::vector<double> sorted = err;
        std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
        const double bound = std::max(1.0, 3.0 * sorted[sorted.size() / 2]);
        size_t kept = 0, changed = 0;
        for (size_t i = 0; i < samples.size(); ++i) {
            const char k = err[i] <= bound;
            changed += k != keep[i];
            keep[i] = k;
            kept += size_t(k);
        }
        if (kept < kMinSamples || changed == 0) break;
    }
    if (passing(p) <= passing(identity)) return model;
    // Within what a camera can do in a frame, checked in double before the conversion to float
    // (a value beyond float's range would not convert).
    if (!(std::fabs(p[0]) < 1e3 && std::fabs(p[1]) < 1e3 && 1.0 + p[2] > 1e-3 && 1.0 + p[2] < 1e3 &&
          std::fabs(p[3]) < double(kBackgroundDepth)))
        return model;
    model.a = float(p[0]);
    model.b = float(p[1]);
    model.c = float(1.0 + p[2]);
    model.d = float(p[3]);
    return model;
}

}  // namespace kestrel
