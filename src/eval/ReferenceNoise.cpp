// ReferenceNoise (eval/Regions.h): the reference's own flicker, from motion-compensated changes
// on flat pixels.
#include <array>
#include <cmath>

#include "eval/Regions.h"

namespace kestrel::eval {

namespace {

/// A pixel's bilinear footprint in the previous frame: top-left tap and weights.
struct Footprint {
    int x0 = 0, y0 = 0;
    std::array<float, 2> wx{}, wy{};
};

/// Variance of the high-pass (centre minus the mean of 8 neighbours) of bilinearly resampled
/// independent noise, in units of the noise's: sum of the squared 4x4 kernel.
double resampledHighPassVariance(const Footprint& f) {
    double c[4][4] = {};
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            const double h = (dx || dy) ? -1.0 / 8.0 : 1.0;
            for (int by = 0; by < 2; ++by)
                for (int bx = 0; bx < 2; ++bx)
                    c[dy + 1 + by][dx + 1 + bx] += h * f.wx[size_t(bx)] * f.wy[size_t(by)];
        }
    double sum = 0;
    for (const auto& row : c)
        for (double v : row) sum += v * v;
    return sum;
}

class Measure {
public:
    Measure(const GBuffer& g, const GBuffer& prev) : g_(g), prev_(prev) {}

    size_t at(int x, int y) const { return size_t(y) * size_t(g_.width) + size_t(x); }

    /// The footprint of (x, y) and its neighbours in the previous frame, if the nine share one
    /// motion (so one kernel describes them) and it lands on the same flat surface.
    bool footprint(int x, int y, Footprint& f) const {
        const size_t i = at(x, y);
        const float mx = g_.motionX[i], my = g_.motionY[i];
        if (!std::isfinite(mx) || !std::isfinite(my)) return false;
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const size_t j = at(x + dx, y + dy);
                if (!(std::fabs(g_.motionX[j] - mx) <= kSameMotion &&
                      std::fabs(g_.motionY[j] - my) <= kSameMotion))
                    return false;
            }
        // Motion points from the pixel centre to where it was; taps are at centres.
        const float px = float(x) + mx, py = float(y) + my;
        // The nine footprints' 4x4 taps (x0 - 1 .. x0 + 2) on screen, with the 3x3 windows
        // sameSurfaceBefore checks around their inner 2x2 (x0 .. x0 + 1).
        if (!(px >= 1.f && py >= 1.f && px < float(g_.width - 2) && py < float(g_.height - 2)))
            return false;
        f.x0 = int(std::floor(px));
        f.y0 = int(std::floor(py));
        const float fx = px - float(f.x0), fy = py - float(f.y0);
        f.wx = {1 - fx, fx};
        f.wy = {1 - fy, fy};
        return sameSurfaceBefore(i, f);
    }

    /// Frame t's value minus frame t-1's resampled at (x, y) + motion of the centre.
    double change(const float* now, const float* before, int x, int y, const Footprint& f) const {
        const size_t a = at(f.x0 + x, f.y0 + y), b = a + size_t(g_.width);
        const double then = f.wy[0] * (f.wx[0] * before[a] + f.wx[1] * before[a + 1]) +
                            f.wy[1] * (f.wx[0] * before[b] + f.wx[1] * before[b + 1]);
        return double(now[at(x, y)]) - then;
    }

private:
    static constexpr float kSameMotion = 0.05f;  // px

    /// Every tap of the nine footprints (4x4 pixels) on the same object with the same albedo,
    /// and on one plane.
    bool sameSurfaceBefore(size_t i, const Footprint& f) const {
        const float a = g_.albedoLum[i];
        for (int y = f.y0 - 1; y <= f.y0 + 2; ++y)
            for (int x = f.x0 - 1; x <= f.x0 + 2; ++x) {
                const size_t j = at(x, y);
                if (!g_.objectId.empty() && prev_.objectId[j] != g_.objectId[i]) return false;
                if (!(std::fabs(prev_.albedoLum[j] - a) <= 0.01f * (a + 0.01f))) return false;
            }
        // The 3x3 windows around the inner 2x2 cover the 4x4, corners included.
        return flatAround(prev_, f.x0, f.y0) && flatAround(prev_, f.x0 + 1, f.y0) &&
               flatAround(prev_, f.x0, f.y0 + 1) && flatAround(prev_, f.x0 + 1, f.y0 + 1);
    }

    const GBuffer& g_;
    const GBuffer& prev_;
};

}  // namespace

void ReferenceNoise::add(const DisplayFrame& now, const DisplayFrame& before, const GBuffer& g,
                         const GBuffer& prev, const std::vector<uint8_t>& flat) {
    if (g.motionX.empty() || g.albedoLum.empty() || prev.albedoLum.empty() ||
        prev.width != g.width || prev.height != g.height ||
        (!g.objectId.empty() && prev.objectId.empty()))
        return;
    const Measure m(g, prev);
    for (int y = 1; y + 1 < g.height; ++y)
        for (int x = 1; x + 1 < g.width; ++x) {
            const size_t i = m.at(x, y);
            Footprint f;
            if (!flat[i] || !m.footprint(x, y, f)) continue;
            f.x0 -= x;  // relative: change() adds each neighbour's own position
            f.y0 -= y;
            const double scale = std::sqrt(2.0 / (9.0 / 8.0 + resampledHighPassVariance(f)));
            for (int c = 0; c < 3; ++c) {
                const float *rt = now.ref.view().channel(c), *rp = before.ref.view().channel(c);
                double around = 0;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx)
                        if (dx || dy) around += m.change(rt, rp, x + dx, y + dy, f);
                floorSum += std::fabs(m.change(rt, rp, x, y, f) - around / 8.0) * scale;
                outputSum += temporalError(now.out.view().channel(c)[i],
                                           before.out.view().channel(c)[i], rt[i], rp[i]);
                ++samples;
            }
        }
}

}  // namespace kestrel::eval
