// ToneMap: operator curves at hand-computed points, exposure, sRGB encoding, stiff inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ToneMapPass.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using namespace kestrel::passes;
using kestrel::testing::PassHarness;

namespace {

// Runs ToneMap on a 1xN row of grey values and returns channel 0.
std::vector<float> toneMapRow(const std::vector<float>& values,
                              const std::map<std::string, ParamValue>& params, int threads = 1) {
    Image in(int(values.size()), 1, Format::Float3);
    for (size_t i = 0; i < values.size(); ++i)
        for (int c = 0; c < 3; ++c) in.at(c, int(i), 0) = values[i];
    auto h = PassHarness::make<ToneMapPass>(in.extent(), params, threads);
    h.bind("color", in);
    h.run();
    std::vector<float> out;
    for (size_t i = 0; i < values.size(); ++i) out.push_back(h.out("color").at(0, int(i), 0));
    return out;
}

}  // namespace

TEST(ToneMap, ReinhardAtHandComputedPoints) {
    auto out =
        toneMapRow({0.f, 1.f, 3.f}, {{"operator", std::string("reinhard")}, {"srgb", false}});
    EXPECT_FLOAT_EQ(out[0], 0.f);
    EXPECT_FLOAT_EQ(out[1], 0.5f);   // 1 / (1 + 1)
    EXPECT_FLOAT_EQ(out[2], 0.75f);  // 3 / (1 + 3)
}

TEST(ToneMap, ExposureIsInStops) {
    // 0.5 * 2^1 = 1 -> Reinhard 0.5; 4 * 2^-2 = 1 -> 0.5.
    auto up = toneMapRow(
        {0.5f}, {{"operator", std::string("reinhard")}, {"srgb", false}, {"exposure", 1.0}});
    auto down = toneMapRow(
        {4.f}, {{"operator", std::string("reinhard")}, {"srgb", false}, {"exposure", -2.0}});
    EXPECT_FLOAT_EQ(up[0], 0.5f);
    EXPECT_FLOAT_EQ(down[0], 0.5f);
}

TEST(ToneMap, AcesFitValues) {
    // Narkowicz fit at x = 1: (2.51 + 0.03) / (2.43 + 0.59 + 0.14) = 2.54 / 3.16.
    auto out = toneMapRow({1.f, 1000.f}, {{"operator", std::string("aces")}, {"srgb", false}});
    EXPECT_NEAR(out[0], 2.54f / 3.16f, 1e-6f);
    EXPECT_FLOAT_EQ(out[1], 1.f);  // saturates (the fit tends to 2.51/2.43 > 1, clamped)
}

TEST(ToneMap, ClampAndSrgb) {
    auto lin =
        toneMapRow({-1.f, 0.25f, 7.f}, {{"operator", std::string("clamp")}, {"srgb", false}});
    EXPECT_FLOAT_EQ(lin[0], 0.f);
    EXPECT_FLOAT_EQ(lin[1], 0.25f);
    EXPECT_FLOAT_EQ(lin[2], 1.f);
    // sRGB: 0.002 is on the linear segment (12.92 x); 0.5 -> 1.055 * 0.5^(1/2.4) - 0.055 =
    // 0.735357.
    auto enc =
        toneMapRow({0.002f, 0.5f, 1.f}, {{"operator", std::string("clamp")}, {"srgb", true}});
    EXPECT_NEAR(enc[0], 0.02584f, 1e-6f);
    EXPECT_NEAR(enc[1], 0.735357f, 1e-5f);
    EXPECT_NEAR(enc[2], 1.f, 1e-6f);
}

TEST(ToneMap, NonFiniteInputsGiveValuesInUnitRange) {
    const float inf = std::numeric_limits<float>::infinity();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (const char* op : {"reinhard", "aces", "clamp"}) {
        auto out = toneMapRow({nan, inf, -inf, 1e30f, -1e30f}, {{"operator", std::string(op)}});
        EXPECT_EQ(out[0], 0.f) << op;
        EXPECT_NEAR(out[1], 1.f, 1e-5f) << op;
        EXPECT_EQ(out[2], 0.f) << op;
        EXPECT_NEAR(out[3], 1.f, 1e-5f) << op;
        EXPECT_EQ(out[4], 0.f) << op;
    }
}

TEST(ToneMap, OneAndTwoThreadsIdentical) {
    Image in(61, 97, Format::Float3);
    for (int c = 0; c < 3; ++c)
        for (int y = 0; y < in.height(); ++y)
            for (int x = 0; x < in.width(); ++x)
                in.at(c, x, y) = float((x * 7 + y * 13 + c) % 97) * 0.13f;
    auto h1 = PassHarness::make<ToneMapPass>(in.extent(), {}, 1);
    auto h2 = PassHarness::make<ToneMapPass>(in.extent(), {}, 2);
    h1.bind("color", in);
    h2.bind("color", in);
    h1.run();
    h2.run();
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < in.extent().pixels(); ++i)
            ASSERT_EQ(h1.out("color").channel(c)[i], h2.out("color").channel(c)[i]);
}
