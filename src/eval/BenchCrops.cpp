// The bench report's crops: where the settings err most, rather than one fixed window that is
// often mostly sky.
#include <algorithm>
#include <cmath>
#include <vector>

#include "eval/BenchReport.h"

namespace kestrel::eval {
namespace {

// Per-pixel relative squared error, averaged over the outputs, as a summed-area table
// (width + 1) x (height + 1) so that any window's sum costs four look-ups.
std::vector<double> errorTable(const std::vector<ImageView>& outputs, const ImageView& ref) {
    const int w = ref.width(), h = ref.height();
    std::vector<double> t(size_t(w + 1) * size_t(h + 1), 0.0);
    auto at = [&](int x, int y) -> double& { return t[size_t(y) * size_t(w + 1) + size_t(x)]; };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double e = 0;
            for (const ImageView& o : outputs)
                for (int c = 0; c < 3; ++c) {
                    const double r = ref.at(std::min(c, ref.channels() - 1), x, y);
                    const double d = o.at(std::min(c, o.channels() - 1), x, y) - r;
                    if (std::isfinite(d)) e += d * d / (r * r + 0.01);
                }
            at(x + 1, y + 1) = e + at(x, y + 1) + at(x + 1, y) - at(x, y);
        }
    return t;
}

bool overlaps(const CropRect& a, const CropRect& b) {
    return a.x0 < b.x0 + b.w && b.x0 < a.x0 + a.w && a.y0 < b.y0 + b.h && b.y0 < a.y0 + a.h;
}

}  // namespace

std::vector<CropRect> worstRegions(const std::vector<ImageView>& outputs, const ImageView& ref,
                                   int size, int count) {
    std::vector<CropRect> chosen;
    if (!ref.valid() || outputs.empty() || size <= 0) return chosen;
    for (const ImageView& o : outputs)
        if (o.extent != ref.extent) return chosen;
    const int w = ref.width(), h = ref.height();
    const int cw = std::min(size, w), ch = std::min(size, h), step = std::max(1, size / 4);
    const std::vector<double> t = errorTable(outputs, ref);
    auto sum = [&](const CropRect& r) {
        auto at = [&](int x, int y) { return t[size_t(y) * size_t(w + 1) + size_t(x)]; };
        return at(r.x0 + r.w, r.y0 + r.h) - at(r.x0, r.y0 + r.h) - at(r.x0 + r.w, r.y0) +
               at(r.x0, r.y0);
    };
    std::vector<CropRect> grid;  // the last row and column flush with the frame's edge
    for (int y = 0;; y = std::min(y + step, h - ch)) {
        for (int x = 0;; x = std::min(x + step, w - cw)) {
            grid.push_back({x, y, cw, ch});
            if (x == w - cw) break;
        }
        if (y == h - ch) break;
    }
    while (int(chosen.size()) < count) {
        const CropRect* best = nullptr;
        double bestSum = -1;
        for (const CropRect& r : grid) {
            if (std::any_of(chosen.begin(), chosen.end(),
                            [&](const CropRect& c) { return overlaps(c, r); }))
                continue;
            if (const double s = sum(r); s > bestSum) bestSum = s, best = &r;
        }
        if (!best) break;
        chosen.push_back(*best);
    }
    return chosen;
}

}  // namespace kestrel::eval
