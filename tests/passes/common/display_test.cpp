// display/ToneMap.h: the one tone-curve and sRGB implementation the ToneMap pass, the PNG
// previews and the metrics share.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "display/ToneMap.h"

using namespace kestrel::display;

TEST(Display, CurveNamesFollowTheEnum) {
    const auto names = toneCurveNames();
    ASSERT_EQ(names.size(), 3u);
    EXPECT_EQ(names[size_t(ToneCurve::Reinhard)], "reinhard");
    EXPECT_EQ(names[size_t(ToneCurve::Aces)], "aces");
    EXPECT_EQ(names[size_t(ToneCurve::Clamp)], "clamp");
}

TEST(Display, SaturationBoundsEveryCurve) {
    const float inf = std::numeric_limits<float>::infinity();
    // Above the saturation a value counts as the saturation: Reinhard of 1e6, not of 1e9.
    EXPECT_EQ(toneMap(1e9f, ToneCurve::Reinhard), toneMap(kSaturation, ToneCurve::Reinhard));
    EXPECT_EQ(toneMap(inf, ToneCurve::Reinhard), 1e6f / (1.f + 1e6f));
    // Aces of a value whose products overflow float is white, not Inf/Inf.
    EXPECT_EQ(toneMap(1e20f, ToneCurve::Aces), 1.f);
    EXPECT_EQ(toneMap(inf, ToneCurve::Clamp), 1.f);
    // A higher saturation (the metrics' 1e30) lets Reinhard approach 1 further.
    EXPECT_GT(toneMap(1e9f, ToneCurve::Reinhard, 1e30f), toneMap(1e9f, ToneCurve::Reinhard));
    EXPECT_EQ(toneMap(inf, ToneCurve::Reinhard, 1e30f), 1.f);
    for (ToneCurve c : {ToneCurve::Reinhard, ToneCurve::Aces, ToneCurve::Clamp}) {
        EXPECT_EQ(toneMap(std::nanf(""), c), 0.f);
        EXPECT_EQ(toneMap(-3.f, c), 0.f);
    }
}

TEST(Display, SrgbRoundTripsAndGamma) {
    for (float v : {0.f, 0.002f, 0.04f, 0.18f, 0.5f, 1.f})
        EXPECT_NEAR(srgbDecode(srgbEncode(v)), v, 1e-6f) << v;
    EXPECT_EQ(srgbEncode(2.f), srgbEncode(1.f));  // clamped
    EXPECT_FLOAT_EQ(gamma22Encode(0.5f), std::pow(0.5f, 1.f / 2.2f));
}
