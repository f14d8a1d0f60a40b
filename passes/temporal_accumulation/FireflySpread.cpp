#include "FireflySpread.h"

#include <kestrel/PixelMath.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <vector>

namespace kestrel::firefly {

void Excess::reset(int height) {
    rows.resize(size_t(std::max(height, 0)));
    for (auto& row : rows) row.clear();
}

namespace {

float luminance(float r, float g, float b) {
    return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}

/// The G-buffer, sanitised where it is read.
struct Gbuffer {
    int w, h;
    const ImageView &depth, &normal;
    const int32_t* ids;  ///< null without object ids

    float z(int x, int y) const { return px::sanitizeDepth(depth.row(0, y)[x]); }
    float n(int c, int x, int y) const { return px::sanitizeNormal(normal.row(c, y)[x]); }
    int32_t id(int x, int y) const { return ids ? ids[size_t(y) * size_t(w) + size_t(x)] : 0; }
};

/// A clamped pixel and the share of its excess per unit of falloff weight.
struct Source {
    int x;
    float s0, s1, s2;
};

/// The clamped pixels of one row, and for each its window's 2r + 1 masks: bit i of mask j says
/// whether pixel (x - r + i, y - r + j) is on its surface.
struct RowSources {
    std::vector<Source> list;
    std::vector<uint64_t> masks;
};

constexpr double kMostTerm = 1e8;  // each luminance term of the window sums is held to this
/// The least share of its excess a source keeps; below, it is dropped as SVGF drops it (a share
/// of under 1/64 moves the image by less than the clamp's rounding of the window).
constexpr double kMinKept = 1.0 / 64.0;

/// The excess's luminance summed over (x, y)'s window: the clamped samples of its rows within
/// [x - r, x + r], found by binary search (each row is in x order).
double excessInWindow(const Excess& e, int x, int y, int r, int h) {
    double sum = 0.0;
    for (int j = std::max(y - r, 0); j <= std::min(y + r, h - 1); ++j) {
        const auto& row = e.rows[size_t(j)];
        auto it = std::lower_bound(row.begin(), row.end(), x - r,
                                   [](const Clamped& c, int v) { return c.x < v; });
        for (; it != row.end() && it->x <= x + r; ++it)
            sum += std::min(kMostTerm, double(luminance(it->e0, it->e1, it->e2)));
    }
    return sum;
}

/// The accumulated colour's luminance summed over (x, y)'s window; once past `limit` (checked
/// row by row), what it has summed so far.
double lightInWindow(const ImageView& color, int x, int y, int r, double limit) {
    const int w = color.width(), h = color.height();
    double sum = 0.0;
    for (int j = std::max(y - r, 0); j <= std::min(y + r, h - 1); ++j) {
        const float *c0 = color.row(0, j), *c1 = color.row(1, j), *c2 = color.row(2, j);
        for (int i = std::max(x - r, 0); i <= std::min(x + r, w - 1); ++i) {
            const float l =
                luminance(px::sanitize(c0[i]), px::sanitize(c1[i]), px::sanitize(c2[i]));
            sum += std::clamp(double(l), 0.0, kMostTerm);
        }
        if (sum > limit) break;
    }
    return sum;
}

/// The weight of a window pixel at (dx, dy) from its source: a Gaussian of sigma r / 2 (the
/// window's edge at 2 sigma), so the spread fades out. An even share over the square window
/// showed as square patches on the zoo fireflies' lit ground (crops of frame 10).
struct Falloff {
    int r;
    std::vector<float> weight, distance;  ///< (2r + 1)^2 each, row-major from (-r, -r)
    explicit Falloff(int radius)
        : r(radius), weight(size_t(2 * r + 1) * size_t(2 * r + 1)), distance(weight.size()) {
        const float twoSigma2 = 2.f * 0.25f * float(r) * float(r);
        for (int dy = -r; dy <= r; ++dy)
            for (int dx = -r; dx <= r; ++dx) {
                const size_t i = size_t(dy + r) * size_t(2 * r + 1) + size_t(dx + r);
                const float d2 = float(dx * dx + dy * dy);
                weight[i] = std::exp(-d2 / twoSigma2);
                distance[i] = std::sqrt(d2);
            }
    }
    const float* row(int dy) const { return weight.data() + size_t(dy + r) * size_t(2 * r + 1); }
    const float* distances(int dy) const {
        return distance.data() + size_t(dy + r) * size_t(2 * r + 1);
    }
};

/// Marks the pixels of (x, y)'s window that lie on its surface: the same object, normals within
/// ~25 degrees, depth within twice the depth slope per pixel of distance (plus 0.1% for a surface
/// facing the camera; the slope is the largest difference to a 4-neighbour, at most 5% of the
/// depth: a silhouette's jump is no slope of this surface). Returns their falloff weights' sum.
float markSurface(const Gbuffer& g, const Falloff& falloff, int x, int y, int r, uint64_t* mask) {
    const float z = g.z(x, y), n0 = g.n(0, x, y), n1 = g.n(1, x, y), n2 = g.n(2, x, y);
    const int32_t id = g.id(x, y);
    float slope = 0.f;
    if (x > 0) slope = std::max(slope, std::fabs(g.z(x - 1, y) - z));
    if (x + 1 < g.w) slope = std::max(slope, std::fabs(g.z(x + 1, y) - z));
    if (y > 0) slope = std::max(slope, std::fabs(g.z(x, y - 1) - z));
    if (y + 1 < g.h) slope = std::max(slope, std::fabs(g.z(x, y + 1) - z));
    slope = std::min(slope, 0.05f * z);
    std::fill(mask, mask + 2 * r + 1, uint64_t(0));
    float total = 0.f;
    for (int j = std::max(y - r, 0); j <= std::min(y + r, g.h - 1); ++j) {
        const float *wrow = falloff.row(j - y), *drow = falloff.distances(j - y);
        const float *zr = g.depth.row(0, j), *nx = g.normal.row(0, j), *ny = g.normal.row(1, j),
                    *nz = g.normal.row(2, j);
        uint64_t bits = 0;
        for (int i = std::max(x - r, 0); i <= std::min(x + r, g.w - 1); ++i) {
            if (g.id(i, j) != id) continue;
            const float dot = n0 * px::sanitizeNormal(nx[i]) + n1 * px::sanitizeNormal(ny[i]) +
                              n2 * px::sanitizeNormal(nz[i]);
            if (!(dot >= 0.9f)) continue;
            const float tolerance = 2.f * slope * drow[i - x + r] + 1e-3f * z;
            if (!(std::fabs(px::sanitizeDepth(zr[i]) - z) <= tolerance)) continue;
            bits |= uint64_t(1) << (i - x + r);
            total += wrow[i - x + r];
        }
        mask[size_t(j - y + r)] = bits;
    }
    return total;
}

}  // namespace

void spreadExcess(const FrameContext& ctx, const Excess& excess, const Surface& surface,
                  SpreadSettings settings, const ImageView& color) {
    const int w = color.width(), h = color.height(), r = std::min(settings.radius, kMaxRadius);
    if (r <= 0 || w <= 0 || h <= 0 || !(settings.fullShare > 0.f) ||
        excess.rows.size() != size_t(h))
        return;
    const Gbuffer g{w, h, *surface.depth, *surface.normal,
                    surface.objectId ? surface.objectId->ints() : nullptr};

    // The clamped pixels of each row, with the share each pixel of their surface receives.
    std::vector<RowSources> sources(static_cast<size_t>(h));
    const size_t window = size_t(2 * r + 1);
    const Falloff falloff(r);
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (const Clamped& c : excess.rows[size_t(y)]) {
                const float most = settings.maxBounds * c.bound;
                if (!(most > 0.f)) continue;
                // f = min(1, E / (E + K) / fullShare); a source below kMinKept is dropped whole,
                // so the light's window sum stops once K is past where f falls below it (the
                // common case: a noise tail in a lit window).
                const double se = excessInWindow(excess, c.x, y, r, h);
                const double kmax = se * (1.0 / (double(settings.fullShare) * kMinKept) - 1.0);
                const double sk = lightInWindow(color, c.x, y, r, kmax);
                const float share = se + sk > 0.0 ? float(se / (se + sk)) : 0.f;
                const float f = std::min(1.f, share / settings.fullShare);
                if (!(f >= float(kMinKept))) continue;
                RowSources& row = sources[size_t(y)];
                row.masks.resize(row.masks.size() + window);
                const float total = markSurface(g, falloff, c.x, y, r,
                                                row.masks.data() + row.masks.size() - window);
                if (!(total > 0.f)) {
                    row.masks.resize(row.masks.size() - window);
                    continue;
                }
                // Per unit of falloff weight; the source's own pixel (weight 1, the largest)
                // held to maxBounds of the bound.
                const float each = f / total * luminance(c.e0, c.e1, c.e2);
                const float k = f / total * (each > most ? px::safeDiv(most, each) : 1.f);
                row.list.push_back({c.x, c.e0 * k, c.e1 * k, c.e2 * k});
            }
    });

    // Gather: each output row adds the shares of the sources within r rows, in row-major order
    // of the sources (a fixed order: the sums do not depend on how rows are split over threads).
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            float *o0 = color.row(0, y), *o1 = color.row(1, y), *o2 = color.row(2, y);
            for (int qy = std::max(y - r, 0); qy <= std::min(y + r, h - 1); ++qy) {
                const RowSources& row = sources[size_t(qy)];
                const float* wrow = falloff.row(y - qy);
                for (size_t k = 0; k < row.list.size(); ++k) {
                    const Source& s = row.list[k];
                    for (uint64_t bits = row.masks[k * window + size_t(y - qy + r)]; bits;
                         bits &= bits - 1) {
                        const int i = std::countr_zero(bits), x = s.x - r + i;
                        o0[x] += s.s0 * wrow[i];
                        o1[x] += s.s1 * wrow[i];
                        o2[x] += s.s2 * wrow[i];
                    }
                }
            }
        }
    });
}

}  // namespace kestrel::firefly
