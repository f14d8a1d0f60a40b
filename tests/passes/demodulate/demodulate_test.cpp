#include <gtest/gtest.h>

#include "../SvgfTestImages.h"
#include "DemodulatePass.h"
#include "ModulatePass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {
Image colorRamp(int w, int h, int seed) {
    Image im(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) im.at(c, x, y) = 0.05f + 4.f * hash01(x, y, seed + c);
    return im;
}
}  // namespace

TEST(Demodulate, DividesEmissionFreeColourByAlbedoAndLeavesBlackAlbedoAlone) {
    Image color = constant(2, 1, Format::Float3, 1.f),
          albedo = constant(2, 1, Format::Float3, 0.5f),
          emission = constant(2, 1, Format::Float3, 0.25f);
    albedo.at(1, 1, 0) = 0.f;  // below the floor: not demodulated (dividing would amplify 100x)
    auto h = PassHarness::make<DemodulatePass>({2, 1}, {{"albedoFloor", 0.01}});
    h.bind("color", color);
    h.bind("albedo", albedo);
    h.bind("emission", emission);
    h.run();
    EXPECT_FLOAT_EQ(h.out("illumination").at(0, 0, 0), 1.5f);   // (1 - 0.25) / 0.5
    EXPECT_FLOAT_EQ(h.out("illumination").at(1, 1, 0), 0.75f);  // (1 - 0.25) / 1
}

// Black albedo without object ids: an emitter's pixel (no light of its own in the colour) gets
// the floor as the albedo Modulate multiplies back by, so what the filters spread into it from
// lit neighbours comes back 1000x smaller; a lit pixel with black albedo (a mirror demodulated by
// a diffuse albedo) keeps 1 and its light. With ids the albedo is 1 for both, as before.
TEST(Demodulate, BlackAlbedoWithoutLightTakesBackOnlyTheFloorWithoutIds) {
    Image color = constant(3, 1, Format::Float3, 0.f), albedo = constant(3, 1, Format::Float3, 0.f);
    Image ids(3, 1, Format::Int32);
    albedo.at(0, 2, 0) = 0.5f;
    color.at(0, 1, 0) = 0.5f;  // the mirror
    color.at(0, 2, 0) = 0.5f;
    for (bool withIds : {false, true}) {
        SCOPED_TRACE(withIds ? "with ids" : "without ids");
        auto h = PassHarness::make<DemodulatePass>({3, 1}, {{"albedoFloor", 0.001}});
        h.bind("color", color);
        h.bind("albedo", albedo);
        if (withIds) h.bind("objectId", ids);
        h.run();
        EXPECT_FLOAT_EQ(h.out("albedo").at(0, 0, 0), withIds ? 1.f : 0.001f);  // the emitter
        EXPECT_EQ(h.out("illumination").at(0, 0, 0), 0.f);
        EXPECT_FLOAT_EQ(h.out("albedo").at(0, 1, 0), 1.f);  // the mirror keeps its light
        EXPECT_FLOAT_EQ(h.out("illumination").at(0, 1, 0), 0.5f);
        EXPECT_FLOAT_EQ(h.out("albedo").at(0, 2, 0), 0.5f);  // above the floor: the albedo
        EXPECT_FLOAT_EQ(h.out("illumination").at(0, 2, 0), 1.f);
    }
}

TEST(Demodulate, ThenModulateIsIdentityWhereAlbedoAboveFloor) {
    const int w = 13, h = 7;
    Image color = colorRamp(w, h, 0), albedo = colorRamp(w, h, 10), emission = colorRamp(w, h, 20);
    for (int threads : {1, 2}) {
        auto d = PassHarness::make<DemodulatePass>({w, h}, {}, threads);
        d.bind("color", color);
        d.bind("albedo", albedo);
        d.bind("emission", emission);
        d.run();
        auto m = PassHarness::make<ModulatePass>({w, h}, {}, threads);
        m.bind("illumination", d.out("illumination"));
        m.bind("albedo", albedo);
        m.bind("emission", emission);
        m.run();
        for (int c = 0; c < 3; ++c)
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    ASSERT_NEAR(m.out("color").at(c, x, y), color.at(c, x, y),
                                2e-6f * std::fabs(color.at(c, x, y)) + 1e-6f);
    }
}

TEST(Demodulate, NonFiniteInputsGiveFiniteOutputs) {
    Image color = constant(4, 1, Format::Float3, 1.f),
          albedo = constant(4, 1, Format::Float3, 0.5f);
    color.at(0, 0, 0) = NAN;
    color.at(1, 1, 0) = INFINITY;
    albedo.at(2, 2, 0) = NAN;
    albedo.at(0, 3, 0) = 0.f;  // albedo 0 under non-zero colour
    color.at(2, 3, 0) = 1e38f;
    auto h = PassHarness::make<DemodulatePass>({4, 1}, {{"albedoFloor", 0.0}});
    h.bind("color", color);
    h.bind("albedo", albedo);
    h.run();
    EXPECT_TRUE(allFinite(h.out("illumination")));
    EXPECT_EQ(h.out("illumination").at(0, 0, 0), 0.f);  // NaN sample -> 0
}
