// Equivalence of the optimised ClampedAccumulation pass with the plain scalar reference
// (ClampedAccumulationReference.h) on random and extreme inputs, every input combination,
// radii 0..5 and 32, parameter ends, 1-3 threads. Tolerance: exact (0 ulp, bitwise identical
// floats including the sign of zero).
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../../ExtremeValues.h"
#include "../SameBits.h"
#include "ClampedAccumulationPass.h"
#include "ClampedAccumulationReference.h"
#include "HwyTargets.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using namespace kestrel::passes;
using kestrel::testing::PassHarness;

using svgftest::sameBits;

namespace {

struct Inputs {
    Image cur, hist, len;
};

Inputs randomInputs(int w, int h, unsigned seed, float extremeFraction) {
    Inputs in{Image(w, h, Format::Float3), Image(w, h, Format::Float3), Image(w, h, Format::Float)};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const std::vector<float> vals = testvalues::extremeValuesAnd({1e18f});
    const int kVals = int(vals.size());
    auto value = [&] {
        if (u(rng) < extremeFraction) return vals[int(u(rng) * kVals) % kVals];
        return 2.f * u(rng) * u(rng) * (u(rng) < 0.03f ? 50.f : 1.f);
    };
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < in.cur.extent().pixels(); ++i) {
            in.cur.channel(c)[i] = value();
            in.hist.channel(c)[i] = value();
        }
    for (size_t i = 0; i < in.len.extent().pixels(); ++i) {
        const float r = u(rng);
        in.len.channel(0)[i] = r < 0.1f ? 0.f : r < 0.12f ? -1.f : r < 0.13f ? NAN : 1.f;
    }
    return in;
}

void expectEquivalent(const Inputs& in, bool withHist, bool withLen, const clampref::Params& p,
                      int threads, const std::string& what) {
    SCOPED_TRACE(what + " hist " + std::to_string(withHist) + " len " + std::to_string(withLen) +
                 " alpha " + std::to_string(p.alpha) + " k " + std::to_string(p.k) + " radius " +
                 std::to_string(p.radius) + " holdCurrent " + std::to_string(p.holdCurrent) +
                 " threads " + std::to_string(threads));
    auto h = PassHarness::make<ClampedAccumulationPass>(in.cur.extent(),
                                                        {{"alpha", double(p.alpha)},
                                                         {"k", double(p.k)},
                                                         {"radius", int64_t(p.radius)},
                                                         {"holdCurrent", p.holdCurrent}},
                                                        threads);
    h.bind("color", in.cur);
    if (withHist) h.bind("history", in.hist);
    if (withLen) h.bind("historyLength", in.len);
    h.run();
    const Image ref =
        clampref::accumulate(in.cur, withHist ? &in.hist : nullptr, withLen ? &in.len : nullptr, p);
    EXPECT_TRUE(sameBits(h.out("color"), ref));
}

void expectEquivalentAll(const Inputs& in, const std::string& what) {
    clampref::Params p;
    for (int radius : {0, 1, 2, 3, 5})
        for (int threads : {1, 2, 3}) {
            p.radius = radius;
            expectEquivalent(in, true, true, p, threads, what);
        }
    p.radius = 3;
    expectEquivalent(in, true, false, p, 2, what);
    expectEquivalent(in, false, false, p, 2, what);
    expectEquivalent(in, false, true, p, 2, what);
    for (float alpha : {0.f, 1.f, 0.37f})
        for (float k : {0.f, 1000.f, 2.5f}) {
            p.alpha = alpha;
            p.k = k;
            expectEquivalent(in, true, true, p, 2, what);
        }
    p = {};
    p.radius = 32;
    expectEquivalent(in, true, true, p, 2, what);
    p = {};
    p.holdCurrent = true;
    for (int threads : {1, 2}) expectEquivalent(in, true, true, p, threads, what);
    p.k = 0.f;
    expectEquivalent(in, true, false, p, 2, what);
}

}  // namespace

// Once per compiled SIMD target this CPU supports (the pass's loops are compiled per target).
class ClampedAccumulationEquivalence : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(ClampedAccumulationEquivalence);

TEST_P(ClampedAccumulationEquivalence, RandomInputs) {
    expectEquivalentAll(randomInputs(97, 61, 1, 0.f), "random");
    expectEquivalentAll(randomInputs(80, 24, 2, 0.f), "random 80x24");
}

TEST_P(ClampedAccumulationEquivalence, ExtremeInputs) {
    expectEquivalentAll(randomInputs(53, 37, 3, 0.05f), "extremes 5%");
    expectEquivalentAll(randomInputs(41, 29, 4, 0.5f), "extremes 50%");
}

TEST_P(ClampedAccumulationEquivalence, ZerosAndDenormals) {
    Inputs in = randomInputs(33, 17, 5, 0.f);
    in.cur.fill(0.f);
    expectEquivalentAll(in, "zero colour");
    in.cur.fill(std::numeric_limits<float>::denorm_min());
    in.hist.fill(-std::numeric_limits<float>::denorm_min());
    expectEquivalentAll(in, "denormals");
}

TEST_P(ClampedAccumulationEquivalence, TinyImages) {
    for (auto [w, h] : {std::pair{1, 1}, {1, 5}, {7, 1}, {2, 2}, {3, 3}, {2, 9}, {9, 2}})
        expectEquivalentAll(randomInputs(w, h, 6, 0.1f),
                            std::to_string(w) + "x" + std::to_string(h));
}
