// Equivalence of the optimised Demodulate pass with the plain scalar reference
// (DemodulateReference.h) on random and extreme inputs, every input combination, albedo floors
// at both ends, 1-3 threads. Tolerance: exact (0 ulp, bitwise identical floats).
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "../SameBits.h"
#include "DemodulatePass.h"
#include "DemodulateReference.h"
#include "HwyTargets.h"
#include "ModulationTestInputs.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using kestrel::testing::PassHarness;

using svgftest::sameBits;

namespace {

void expectEquivalent(int w, int h, unsigned seed, float extremes) {
    const Image color = modtest::randomImage(w, h, seed, 4.f, extremes);
    const Image albedo = modtest::randomImage(w, h, seed + 1, 1.f, extremes);
    const Image emission = modtest::randomImage(w, h, seed + 2, 0.5f, extremes);
    Image ids(w, h, Format::Int32);
    for (int bound = 1; bound < 8; ++bound) {  // albedo and/or emission (neither: forwarded), ids
        if ((bound & 3) == 0) continue;
        for (double floor : {0.0, 1e-3, 1.0})
            for (int threads : {1, 2, 3}) {
                SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h) + " extremes " +
                             std::to_string(extremes) + " inputs " + std::to_string(bound) +
                             " floor " + std::to_string(floor) + " threads " +
                             std::to_string(threads));
                auto hr =
                    PassHarness::make<DemodulatePass>({w, h}, {{"albedoFloor", floor}}, threads);
                hr.bind("color", color);
                if (bound & 1) hr.bind("albedo", albedo);
                if (bound & 2) hr.bind("emission", emission);
                if (bound & 4) hr.bind("objectId", ids);
                hr.run();
                const demodref::Outputs ref = demodref::demodulate(
                    color, bound & 1 ? &albedo : nullptr, bound & 2 ? &emission : nullptr,
                    float(floor), (bound & 4) != 0);
                EXPECT_TRUE(sameBits(hr.out("illumination"), ref.illumination));
                if (bound & 1) {
                    EXPECT_TRUE(sameBits(hr.out("albedo"), ref.albedo));
                }
            }
    }
}

}  // namespace

// Once per compiled SIMD target this CPU supports (the pass's loops are compiled per target).
class DemodulateEquivalence : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(DemodulateEquivalence);

TEST_P(DemodulateEquivalence, RandomInputs) {
    expectEquivalent(97, 61, 1, 0.f);
    expectEquivalent(64, 8, 2, 0.f);
}

TEST_P(DemodulateEquivalence, ExtremeInputs) {
    expectEquivalent(53, 37, 3, 0.1f);
    expectEquivalent(41, 29, 4, 0.6f);
}

TEST_P(DemodulateEquivalence, TinyImages) {
    for (auto [w, h] : {std::pair{1, 1}, {1, 5}, {7, 1}, {3, 3}}) expectEquivalent(w, h, 5, 0.2f);
}
