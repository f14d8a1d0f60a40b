#include <gtest/gtest.h>

#include "../SvgfTestImages.h"
#include "VarianceEstimationPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {
struct In {
    Image color, moments, length, var, depth, normal;
};
In uniform(int w, int h, float c, float m1, float m2, float len) {
    In in{constant(w, h, Format::Float3, c),  Image(w, h, Format::Float2),
          constant(w, h, Format::Float, len), constant(w, h, Format::Float, 0.123f),
          constant(w, h, Format::Float, 4.f), normals(w, h, 0, 0, 1)};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            in.moments.at(0, x, y) = m1;
            in.moments.at(1, x, y) = m2;
        }
    return in;
}
PassHarness run(const In& in, int threads = 1) {
    auto h = PassHarness::make<VarianceEstimationPass>(in.color.extent(), {}, threads);
    h.bind("color", in.color);
    h.bind("moments", in.moments);
    h.bind("historyLength", in.length);
    h.bind("variance", in.var);
    h.bind("depth", in.depth);
    h.bind("normal", in.normal);
    h.run();
    return h;
}
}  // namespace

TEST(VarianceEstimation, ShortHistoryUsesBoostedSpatialMoments) {
    for (float len : {1.f, 2.f}) {
        In in = uniform(9, 9, 0.5f, 1.f, 1.5f, len);
        auto h = run(in);
        // (m2 - m1^2) * 4 / historyLength = 0.5 * 4 / len
        EXPECT_NEAR(h.out("variance").at(0, 4, 4), 2.f / len, 1e-5f);
        EXPECT_NEAR(h.out("color").at(1, 4, 4), 0.5f, 1e-6f);  // constant stays constant
    }
}

TEST(VarianceEstimation, LongHistoryPassesThrough) {
    In in = uniform(5, 5, 0.5f, 1.f, 1.5f, 4.f);
    in.color.at(0, 2, 2) = 7.f;
    auto h = run(in);
    EXPECT_FLOAT_EQ(h.out("variance").at(0, 2, 2), 0.123f);
    EXPECT_FLOAT_EQ(h.out("color").at(0, 2, 2), 7.f);
}

TEST(VarianceEstimation, NoLeakAcrossDepthEdge) {
    const int w = 14, h = 7;
    In in = uniform(w, h, 0.f, 0.f, 0.f, 1.f);
    for (int y = 0; y < h; ++y)
        for (int x = 7; x < w; ++x) {
            in.depth.at(0, x, y) = 9.f;
            for (int c = 0; c < 3; ++c) in.color.at(c, x, y) = 0.05f;  // within sigmaL of 0
            in.moments.at(0, x, y) = 100.f;
            in.moments.at(1, x, y) = 20000.f;
        }
    auto hr = run(in);
    float leak = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < 7; ++x)
            leak = std::max({leak, hr.out("variance").at(0, x, y), hr.out("color").at(0, x, y)});
    EXPECT_LT(leak, 1e-6f);  // measured 0: constant depth per side, slope 0, weight exactly 0
}

TEST(VarianceEstimation, NonFiniteInputsGiveFiniteOutputs) {
    In in = uniform(6, 6, 0.5f, 1.f, 1.5f, 1.f);
    in.color.at(0, 1, 1) = NAN;
    in.moments.at(1, 2, 2) = INFINITY;
    in.moments.at(0, 3, 3) = NAN;
    in.length.at(0, 4, 4) = NAN;
    in.depth.at(0, 2, 3) = NAN;
    in.normal.at(2, 3, 2) = NAN;
    in.var.at(0, 0, 0) = NAN;
    auto h = run(in);
    EXPECT_TRUE(allFinite(h.out("color")));
    EXPECT_TRUE(allFinite(h.out("variance")));
}

TEST(VarianceEstimation, IdenticalWithOneAndTwoThreads) {
    const int w = 33, hgt = 140;
    In in = uniform(w, hgt, 0.f, 0.f, 0.f, 1.f);
    in.color = grey(w, hgt, [](int x, int y) { return hash01(x, y); });
    in.length =
        scalar(w, hgt, [](int x, int y) { return 1.f + std::floor(6.f * hash01(x, y, 2)); });
    in.depth =
        scalar(w, hgt, [](int x, int y) { return 3.f + 0.02f * float(x) + (y > 60 ? 1.f : 0.f); });
    for (int y = 0; y < hgt; ++y)
        for (int x = 0; x < w; ++x) {
            in.moments.at(0, x, y) = hash01(x, y);
            in.moments.at(1, x, y) = hash01(x, y) * hash01(x, y) + hash01(x, y, 5);
        }
    auto a = run(in, 1), b = run(in, 2);
    EXPECT_TRUE(identical(a.out("color"), b.out("color")));
    EXPECT_TRUE(identical(a.out("variance"), b.out("variance")));
}
