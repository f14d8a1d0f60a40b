// Equivalence of the optimised TAA pass with the plain scalar reference (TaaReference.h) on
// random and extreme inputs, every parameter combination and 1-3 threads. Tolerance: exact
// (0 ulp, bitwise identical floats including the sign of zero).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../../ExtremeValues.h"
#include "../SameBits.h"
#include "HwyTargets.h"
#include "TaaPass.h"
#include "TaaReference.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using namespace kestrel::passes;
using kestrel::testing::PassHarness;

using svgftest::sameBits;

namespace {

struct Inputs {
    Image cur, hist, len, blur;
};

Inputs randomInputs(int w, int h, unsigned seed, float extremeFraction) {
    Inputs in{Image(w, h, Format::Float3), Image(w, h, Format::Float3), Image(w, h, Format::Float),
              Image(w, h, Format::Float)};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const std::vector<float> vals = testvalues::extremeValuesAnd({1e18f, 65504.f});
    const int kVals = int(vals.size());
    auto value = [&](float scale) {
        if (u(rng) < extremeFraction) return vals[int(u(rng) * kVals) % kVals];
        return scale * u(rng) * u(rng) * (u(rng) < 0.05f ? 50.f : 1.f);  // HDR-ish, fireflies
    };
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < in.cur.extent().pixels(); ++i) {
            in.cur.channel(c)[i] = value(2.f);
            in.hist.channel(c)[i] = value(2.f);
        }
    for (size_t i = 0; i < in.len.extent().pixels(); ++i) {
        const float r = u(rng);
        // Validity flags, and ages as TAA's own fed-back historyLength brings them (warmUp).
        in.len.channel(0)[i] = r < 0.1f    ? 0.f
                               : r < 0.12f ? -1.f
                               : r < 0.13f ? NAN
                               : r < 0.14f ? INFINITY
                               : r < 0.5f  ? 1.f
                                           : 1.f + std::floor(300.f * u(rng) * u(rng));
        const float b = u(rng);  // resampleBlur: [0, 1], and what a user's wiring may bring
        in.blur.channel(0)[i] = b < 0.05f ? NAN : b < 0.1f ? -2.f : b < 0.15f ? 7.f : u(rng);
    }
    return in;
}

void expectEquivalent(const Inputs& in, bool withHist, bool withLen, const taaref::Params& p,
                      int threads, const std::string& what, bool withBlur = false) {
    SCOPED_TRACE(what + " hist " + std::to_string(withHist) + " len " + std::to_string(withLen) +
                 " alpha " + std::to_string(p.alpha) + " gamma " + std::to_string(p.gamma) +
                 " clip " + std::to_string(p.clip) + " antiFlicker " +
                 std::to_string(p.antiFlicker) + " threads " + std::to_string(threads) + " blur " +
                 std::to_string(withBlur) + " blurAlpha " + std::to_string(p.blurAlpha) +
                 " warmUp " + std::to_string(p.warmUp));
    auto h = PassHarness::make<TaaPass>(in.cur.extent(),
                                        {{"alpha", double(p.alpha)},
                                         {"gamma", double(p.gamma)},
                                         {"mode", std::string(p.clip ? "clip" : "clamp")},
                                         {"antiFlicker", p.antiFlicker},
                                         {"blurAlpha", double(p.blurAlpha)},
                                         {"warmUp", p.warmUp}},
                                        threads);
    h.bind("color", in.cur);
    if (withHist) h.bind("history", in.hist);
    if (withLen) h.bind("historyLength", in.len);
    if (withBlur) h.bind("resampleBlur", in.blur);
    h.run();
    Image refAge;
    const Image ref =
        taaref::taa(in.cur, withHist ? &in.hist : nullptr, withLen ? &in.len : nullptr, p,
                    withBlur ? &in.blur : nullptr, &refAge);
    EXPECT_TRUE(sameBits(h.out("color"), ref));
    if (withHist) {
        EXPECT_TRUE(sameBits(h.out("historyLength"), refAge, 1));
    }
}

void expectEquivalentAll(const Inputs& in, const std::string& what) {
    for (bool clip : {true, false})
        for (bool anti : {true, false})
            for (int threads : {1, 2, 3}) {
                taaref::Params p;
                p.clip = clip;
                p.antiFlicker = anti;
                expectEquivalent(in, true, true, p, threads, what);
            }
    taaref::Params p;
    expectEquivalent(in, true, false, p, 2, what);
    expectEquivalent(in, false, false, p, 2, what);
    expectEquivalent(in, false, true, p, 2, what);
    for (float alpha : {0.f, 1.f, 0.37f})
        for (float gamma : {0.f, 100.f, 2.5f}) {
            p.alpha = alpha;
            p.gamma = gamma;
            expectEquivalent(in, true, true, p, 2, what);
        }
    for (bool warmUp : {true, false})
        for (int threads : {1, 2, 3}) {
            taaref::Params q;
            q.warmUp = warmUp;
            expectEquivalent(in, true, true, q, threads, what, true);
            q.clip = false;
            q.antiFlicker = false;
            expectEquivalent(in, true, true, q, threads, what);
        }
    taaref::Params warm;
    warm.warmUp = true;
    expectEquivalent(in, true, false, warm, 2, what);  // no age fed: no warm-up
    for (bool clip : {true, false})
        for (float blurAlpha : {1.f, 0.f, 0.4f}) {
            taaref::Params q;
            q.clip = clip;
            q.blurAlpha = blurAlpha;
            expectEquivalent(in, true, true, q, 2, what, true);
            expectEquivalent(in, true, false, q, 1, what, true);
        }
}

}  // namespace

// Once per compiled SIMD target this CPU supports (the pass's loops are compiled per target).
class TaaEquivalence : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(TaaEquivalence);

TEST_P(TaaEquivalence, RandomInputs) {
    expectEquivalentAll(randomInputs(97, 61, 1, 0.f), "random");
    expectEquivalentAll(randomInputs(64, 32, 2, 0.f), "random 64x32");
}

TEST_P(TaaEquivalence, ExtremeInputs) {
    expectEquivalentAll(randomInputs(53, 37, 3, 0.05f), "extremes 5%");
    expectEquivalentAll(randomInputs(41, 29, 4, 0.5f), "extremes 50%");
}

TEST_P(TaaEquivalence, ZerosAndDenormals) {
    Inputs in = randomInputs(33, 17, 5, 0.f);
    in.cur.fill(0.f);
    expectEquivalentAll(in, "zero colour");
    in.cur.fill(std::numeric_limits<float>::denorm_min());
    in.hist.fill(-std::numeric_limits<float>::denorm_min());
    expectEquivalentAll(in, "denormals");
}

TEST_P(TaaEquivalence, TinyImages) {
    for (auto [w, h] : {std::pair{1, 1}, {1, 5}, {7, 1}, {2, 2}, {3, 3}, {2, 9}, {9, 2}})
        expectEquivalentAll(randomInputs(w, h, 6, 0.1f),
                            std::to_string(w) + "x" + std::to_string(h));
}
