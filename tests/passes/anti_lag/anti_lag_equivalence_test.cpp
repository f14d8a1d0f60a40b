// Equivalence of the AntiLag pass, on every compiled SIMD target, with a plain per-pixel
// reference (below: each pixel's window summed directly, row sums left to right, then rows top
// to bottom, as the pass orders them) on random and extreme inputs, radii 1-16, 1-3 threads.
// Tolerance: exact (0 ulp): the pass is built without contraction and sums in a fixed order.
#include <gtest/gtest.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <random>
#include <string>

#include "../demodulate/ModulationTestInputs.h"
#include "AntiLagPass.h"
#include "HwyTargets.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using kestrel::testing::PassHarness;

namespace {

bool validLength(float h) {
    return h > 0.f && h <= std::numeric_limits<float>::max();
}

float luminance(const Image& im, int x, int y) {
    auto s = [](float v) { return px::sanitize(v); };
    const float l =
        0.2126f * s(im.at(0, x, y)) + 0.7152f * s(im.at(1, x, y)) + 0.0722f * s(im.at(2, x, y));
    return std::max(l, 0.f);
}

/// The gated length of pixel (x, y): AntiLagPass.h's formula, written out plainly.
float reference(const Image& color, const Image& history, const Image& length, int x, int y, int r,
                float sigma) {
    const float hl = length.at(0, x, y);
    if (!validLength(hl)) return 0.f;
    const int w = color.width(), h = color.height();
    float n = 0.f, c = 0.f, c2 = 0.f, hs = 0.f;
    bool first = true;
    for (int yy = std::max(0, y - r); yy <= std::min(h - 1, y + r); ++yy) {
        float rn = 0.f, rc = 0.f, rc2 = 0.f, rh = 0.f;  // this row's sums, left to right
        for (int xx = x - r; xx <= x + r; ++xx) {
            const bool v = xx >= 0 && xx < w && validLength(length.at(0, xx, yy));
            const float lc = v ? luminance(color, xx, yy) : 0.f;
            rn += v ? 1.f : 0.f;
            rc += lc;
            rc2 += lc * lc;
            rh += v ? luminance(history, xx, yy) : 0.f;
        }
        n = first ? rn : n + rn;
        c = first ? rc : c + rc;
        c2 = first ? rc2 : c2 + rc2;
        hs = first ? rh : hs + rh;
        first = false;
    }
    n = std::max(n, 1.f);
    const float mc = c / n, mh = hs / n;
    const float stdErr = std::sqrt(std::max(0.f, c2 / n - mc * mc) / n);
    const float excess = std::max(0.f, std::fabs(mh - mc) - sigma * stdErr);
    const float scale = std::min(mh, mc);
    const float lambda = std::min(1.f, excess / std::max(scale, std::numeric_limits<float>::min()));
    const float l = std::min(hl, 1e6f);
    return l * (1.f - lambda) / (1.f + lambda * l);
}

void expectEquivalent(int w, int h, unsigned seed, float extremes,
                      std::initializer_list<int> radii = {1, 2, 4}) {
    const Image color = modtest::randomImage(w, h, seed, 2.f, extremes);
    const Image history = modtest::randomImage(w, h, seed + 1, 2.f, extremes);
    Image length(w, h, Format::Float);
    std::mt19937 rng(seed + 2);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const float odd[] = {0.f, -1.f, NAN, INFINITY, 1e30f, 3e-39f};
    for (size_t i = 0; i < length.extent().pixels(); ++i)
        length.channel(0)[i] = u(rng) < 0.2f ? odd[int(u(rng) * 6) % 6] : 1.f + 30.f * u(rng);
    for (int r : radii)
        for (double sigma : {0.0, 4.0})
            for (int threads : {1, 2, 3}) {
                SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h) + " radius " +
                             std::to_string(r) + " sigma " + std::to_string(sigma) + " threads " +
                             std::to_string(threads));
                auto hr = PassHarness::make<AntiLagPass>(
                    {w, h}, {{"radius", int64_t(r)}, {"sigma", sigma}}, threads);
                hr.bind("color", color);
                hr.bind("history", history);
                hr.bind("historyLength", length);
                hr.run();
                const Image& out = hr.out("historyLength");
                for (int y = 0; y < h; ++y)
                    for (int x = 0; x < w; ++x) {
                        const float want = reference(color, history, length, x, y, r, float(sigma));
                        const float got = out.at(0, x, y);
                        ASSERT_EQ(std::memcmp(&got, &want, sizeof(float)), 0)
                            << "pixel (" << x << ", " << y << "): pass " << got << " reference "
                            << want;
                    }
            }
}

}  // namespace

// Once per compiled SIMD target this CPU supports.
class AntiLagEquivalence : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(AntiLagEquivalence);

TEST_P(AntiLagEquivalence, RandomInputs) {
    expectEquivalent(97, 61, 1, 0.f);
    expectEquivalent(64, 8, 2, 0.f);
}

TEST_P(AntiLagEquivalence, ExtremeInputs) {
    expectEquivalent(53, 37, 3, 0.1f);
}

// Tall enough that a thread's band holds many rows (the row ring is reused: bands are up to 16
// rows, and only images of 128 rows or more get bands longer than one row), at the widest radius.
TEST_P(AntiLagEquivalence, TallImagesReuseTheRowRing) {
    expectEquivalent(5, 130, 6, 0.05f, {1, 3, 16});
    expectEquivalent(65, 1040, 7, 0.f, {4});
}

TEST_P(AntiLagEquivalence, TinyImages) {
    for (auto [w, h] : {std::pair{1, 1}, {1, 5}, {7, 1}, {3, 3}}) expectEquivalent(w, h, 5, 0.2f);
}
