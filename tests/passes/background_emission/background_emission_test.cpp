#include <gtest/gtest.h>

#include <cmath>

#include "../SvgfTestImages.h"
#include "BackgroundEmissionPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {
// Three pixels: a surface, the background (1e10) and a broken depth (NaN counts as background).
struct Frame {
    Image color = grey(3, 1, [](int x, int) { return 1.f + float(x); });
    Image depth = constant(3, 1, Format::Float, 5.f);
    Image emission = constant(3, 1, Format::Float3, 0.25f);
    Frame() {
        depth.at(0, 1, 0) = 1e10f;
        depth.at(0, 2, 0) = NAN;
    }
};
}  // namespace

TEST(BackgroundEmission, BackgroundJoinsTheEmission) {
    Frame f;
    auto h = PassHarness::make<BackgroundEmissionPass>({3, 1}, {});
    h.bind("color", f.color);
    h.bind("depth", f.depth);
    h.bind("emission", f.emission);
    h.run();
    for (int c = 0; c < 3; ++c) {
        EXPECT_FLOAT_EQ(h.out("emission").at(c, 0, 0), 0.25f);  // a surface keeps its own
        EXPECT_FLOAT_EQ(h.out("emission").at(c, 1, 0), 2.f);    // the background is its colour
        EXPECT_FLOAT_EQ(h.out("emission").at(c, 2, 0), 3.f);
    }
}

TEST(BackgroundEmission, WithoutEmissionSurfacesHaveNone) {
    Frame f;
    f.color.at(1, 1, 0) = INFINITY;
    auto h = PassHarness::make<BackgroundEmissionPass>({3, 1}, {});
    h.bind("color", f.color);
    h.bind("depth", f.depth);
    h.run();
    EXPECT_EQ(h.out("emission").at(0, 0, 0), 0.f);
    EXPECT_FLOAT_EQ(h.out("emission").at(0, 1, 0), 2.f);
    EXPECT_TRUE(allFinite(h.out("emission")));
}
