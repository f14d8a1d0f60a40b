// Equivalence of the optimised TemporalAccumulation pass with the plain scalar reference
// (TemporalAccumulationReference.h) on random and extreme inputs, every input combination and
// parameter ends, 1-3 threads. Tolerance: exact (0 ulp, bitwise identical floats including
// the sign of zero).
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../../ExtremeValues.h"
#include "../SameBits.h"
#include "HwyTargets.h"
#include "TemporalAccumulationPass.h"
#include "TemporalAccumulationReference.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using kestrel::testing::PassHarness;

using svgftest::sameBits;

namespace {

struct Inputs {
    Image color, prevColor, prevMoments, prevLength;
};

Inputs randomInputs(int w, int h, unsigned seed, float extremeFraction) {
    Inputs in{Image(w, h, Format::Float3), Image(w, h, Format::Float3), Image(w, h, Format::Float2),
              Image(w, h, Format::Float)};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const std::vector<float> vals = testvalues::extremeValuesAnd({1e16f, 2e6f});
    const int kVals = int(vals.size());
    auto value = [&](float scale) {
        if (u(rng) < extremeFraction) return vals[int(u(rng) * kVals) % kVals];
        // HDR-ish radiance with fireflies.
        return scale * u(rng) * u(rng) * (u(rng) < 0.03f ? 1000.f : 1.f);
    };
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < in.color.extent().pixels(); ++i) {
            in.color.channel(c)[i] = value(1.f);
            in.prevColor.channel(c)[i] = value(1.f);
        }
    for (size_t i = 0; i < in.color.extent().pixels(); ++i) {
        const float m1 = value(1.f);
        in.prevMoments.channel(0)[i] = m1;
        in.prevMoments.channel(1)[i] = u(rng) < 0.9f ? m1 * m1 * (1.f + u(rng)) : value(3.f);
        const float r = u(rng);
        in.prevLength.channel(0)[i] = r < 0.1f    ? 0.f
                                      : r < 0.15f ? value(50.f)
                                                  : std::floor(1.f + 40.f * u(rng));
    }
    return in;
}

void expectEquivalent(const Inputs& in, int bound, const taccref::Params& p, int threads,
                      const std::string& what) {
    const bool hasC = bound & 1, hasM = bound & 2, hasL = bound & 4;
    SCOPED_TRACE(what + " inputs " + std::to_string(bound) + " alpha " + std::to_string(p.alpha) +
                 " momentsAlpha " + std::to_string(p.momentsAlpha) + " cap " +
                 std::to_string(p.maxHistoryLength) + " k " + std::to_string(p.fireflySigma) +
                 " threads " + std::to_string(threads));
    auto h = PassHarness::make<TemporalAccumulationPass>(
        in.color.extent(),
        {{"alpha", double(p.alpha)},
         {"momentsAlpha", double(p.momentsAlpha)},
         {"maxHistoryLength", double(p.maxHistoryLength)},
         {"fireflySigma", double(p.fireflySigma)}},
        threads);
    h.bind("color", in.color);
    if (hasC) h.bind("prevColor", in.prevColor);
    if (hasM) h.bind("prevMoments", in.prevMoments);
    if (hasL) h.bind("prevHistoryLength", in.prevLength);
    h.run();
    const auto ref =
        taccref::accumulate(in.color, hasC ? &in.prevColor : nullptr,
                            hasM ? &in.prevMoments : nullptr, hasL ? &in.prevLength : nullptr, p);
    EXPECT_TRUE(sameBits(h.out("color"), ref.color)) << "color";
    EXPECT_TRUE(sameBits(h.out("moments"), ref.moments)) << "moments";
    EXPECT_TRUE(sameBits(h.out("historyLength"), ref.historyLength)) << "historyLength";
    EXPECT_TRUE(sameBits(h.out("variance"), ref.variance)) << "variance";
}

void expectEquivalentAll(const Inputs& in, const std::string& what) {
    taccref::Params p;
    for (int bound = 0; bound < 8; ++bound)
        for (int threads : {1, 2, 3}) expectEquivalent(in, bound, p, threads, what);
    for (float alpha : {0.f, 1.f})
        for (float k : {0.f, 1e6f, 0.5f})
            for (float cap : {1.f, 1e6f}) {
                p.alpha = p.momentsAlpha = alpha;
                p.fireflySigma = k;
                p.maxHistoryLength = cap;
                expectEquivalent(in, 7, p, 2, what);
            }
}

}  // namespace

// Once per compiled SIMD target this CPU supports (the pass's loops are compiled per target).
class TemporalAccumulationEquivalence : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(TemporalAccumulationEquivalence);

TEST_P(TemporalAccumulationEquivalence, RandomInputs) {
    expectEquivalentAll(randomInputs(97, 61, 1, 0.f), "random");
    expectEquivalentAll(randomInputs(64, 40, 2, 0.f), "random 64x40");
}

TEST_P(TemporalAccumulationEquivalence, ExtremeInputs) {
    expectEquivalentAll(randomInputs(53, 37, 3, 0.05f), "extremes 5%");
    expectEquivalentAll(randomInputs(41, 29, 4, 0.5f), "extremes 50%");
}

TEST_P(TemporalAccumulationEquivalence, ZerosAndDenormals) {
    Inputs in = randomInputs(33, 17, 5, 0.f);
    in.color.fill(0.f);
    expectEquivalentAll(in, "zero colour");
    in.color.fill(std::numeric_limits<float>::denorm_min());
    in.prevMoments.fill(-std::numeric_limits<float>::denorm_min());
    expectEquivalentAll(in, "denormals");
}

TEST_P(TemporalAccumulationEquivalence, TinyImages) {
    for (auto [w, h] : {std::pair{1, 1}, {1, 5}, {7, 1}, {2, 2}, {3, 3}, {2, 9}, {9, 2}})
        expectEquivalentAll(randomInputs(w, h, 6, 0.1f),
                            std::to_string(w) + "x" + std::to_string(h));
}
