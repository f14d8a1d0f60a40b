// Equivalence of the optimised Modulate pass with the plain scalar reference
// (ModulateReference.h) on random and extreme inputs, every input combination, albedo floors
// at both ends, 1-3 threads. Tolerance: exact (0 ulp, bitwise identical floats).
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "../SameBits.h"
#include "../demodulate/ModulationTestInputs.h"
#include "HwyTargets.h"
#include "ModulatePass.h"
#include "ModulateReference.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using kestrel::testing::PassHarness;

using svgftest::sameBits;

namespace {

void expectEquivalent(int w, int h, unsigned seed, float extremes) {
    const Image color = modtest::randomImage(w, h, seed, 4.f, extremes);
    const Image albedo = modtest::randomImage(w, h, seed + 1, 1.f, extremes);
    const Image emission = modtest::randomImage(w, h, seed + 2, 0.5f, extremes);
    const Image base = modtest::randomImage(w, h, seed + 3, 2.f, extremes);
    for (int bound = 1; bound < 8; ++bound)  // albedo, emission, base (none: forwarded)
        for (double floor : {0.0, 1e-3, 1.0})
            for (int threads : {1, 2, 3}) {
                SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h) + " extremes " +
                             std::to_string(extremes) + " inputs " + std::to_string(bound) +
                             " floor " + std::to_string(floor) + " threads " +
                             std::to_string(threads));
                auto hr =
                    PassHarness::make<ModulatePass>({w, h}, {{"albedoFloor", floor}}, threads);
                hr.bind("illumination", color);
                if (bound & 1) hr.bind("albedo", albedo);
                if (bound & 2) hr.bind("emission", emission);
                if (bound & 4) hr.bind("base", base);
                hr.run();
                const Image ref = modref::modulate(color, bound & 1 ? &albedo : nullptr,
                                                   bound & 2 ? &emission : nullptr,
                                                   bound & 4 ? &base : nullptr, float(floor));
                EXPECT_TRUE(sameBits(hr.out("color"), ref));
            }
}

}  // namespace

// Once per compiled SIMD target this CPU supports (the pass's loops are compiled per target).
class ModulateEquivalence : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(ModulateEquivalence);

TEST_P(ModulateEquivalence, RandomInputs) {
    expectEquivalent(97, 61, 1, 0.f);
    expectEquivalent(64, 8, 2, 0.f);
}

TEST_P(ModulateEquivalence, ExtremeInputs) {
    expectEquivalent(53, 37, 3, 0.1f);
    expectEquivalent(41, 29, 4, 0.6f);
}

TEST_P(ModulateEquivalence, TinyImages) {
    for (auto [w, h] : {std::pair{1, 1}, {1, 5}, {7, 1}, {3, 3}}) expectEquivalent(w, h, 5, 0.2f);
}
