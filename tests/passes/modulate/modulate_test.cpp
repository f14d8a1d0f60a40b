#include <gtest/gtest.h>

#include "../SvgfTestImages.h"
#include "ModulatePass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

TEST(Modulate, MultipliesAlbedoAddsEmissionAndBase) {
    Image illum = constant(2, 1, Format::Float3, 2.f),
          albedo = constant(2, 1, Format::Float3, 0.5f),
          emission = constant(2, 1, Format::Float3, 0.25f),
          base = constant(2, 1, Format::Float3, 3.f);
    albedo.at(2, 1, 0) = 0.f;  // below the floor: multiplied by 1, as Demodulate divided by 1
    auto h = PassHarness::make<ModulatePass>({2, 1});
    h.bind("illumination", illum);
    h.bind("albedo", albedo);
    h.bind("emission", emission);
    h.bind("base", base);
    h.run();
    EXPECT_FLOAT_EQ(h.out("color").at(0, 0, 0), 2.f * 0.5f + 0.25f + 3.f);
    EXPECT_FLOAT_EQ(h.out("color").at(2, 1, 0), 2.f * 1.f + 0.25f + 3.f);
}

TEST(Modulate, NonFiniteInputsGiveFiniteOutputs) {
    Image illum = constant(3, 1, Format::Float3, 1.f),
          albedo = constant(3, 1, Format::Float3, 0.5f), base = constant(3, 1, Format::Float3, 1.f);
    illum.at(0, 0, 0) = NAN;
    albedo.at(1, 1, 0) = INFINITY;
    base.at(2, 2, 0) = -INFINITY;
    auto h = PassHarness::make<ModulatePass>({3, 1});
    h.bind("illumination", illum);
    h.bind("albedo", albedo);
    h.bind("base", base);
    h.run();
    EXPECT_TRUE(allFinite(h.out("color")));
}
