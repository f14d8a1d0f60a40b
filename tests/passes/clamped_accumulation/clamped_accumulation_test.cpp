// ClampedAccumulation: the GAMES202 formula on hand-computed cases, alpha = 1 where the
// projection failed, stiff inputs, thread-count independence.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "ClampedAccumulationPass.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using namespace kestrel::passes;
using kestrel::testing::PassHarness;

namespace {

Image grey(int w, int h, float v) {
    Image img(w, h, Format::Float3);
    img.fill(v);
    return img;
}

void setGrey(Image& img, int x, int y, float v) {
    for (int c = 0; c < 3; ++c) img.at(c, x, y) = v;
}

}  // namespace

TEST(ClampedAccumulation, HandComputed3x3Window) {
    // radius 1, k 1, alpha 0.2. Centre (1,1) of a 3x3 image holding 0.1 .. 0.9:
    //   mu = 0.5, sigma^2 = mean(v^2) - mu^2 = 2.85/9 - 0.25 = 0.0666667, sigma = 0.2581989.
    // History 2.0 is clamped to mu + sigma = 0.7581989:
    //   out = 0.2 * 0.5 + 0.8 * 0.7581989 = 0.7065591.
    // History 0.6 lies inside the box: out = 0.2 * 0.5 + 0.8 * 0.6 = 0.58.
    Image cur(3, 3, Format::Float3);
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 3; ++x) setGrey(cur, x, y, 0.1f * float(1 + x + 3 * y));
    Image hist = grey(3, 3, 2.f);
    setGrey(hist, 1, 1, 2.f);
    auto h = PassHarness::make<ClampedAccumulationPass>({3, 3}, {{"radius", int64_t(1)}});
    h.bind("color", cur);
    h.bind("history", hist);
    h.run();
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(h.out("color").at(c, 1, 1), 0.7065591f, 1e-6f);
    setGrey(hist, 1, 1, 0.6f);
    h.run();
    EXPECT_NEAR(h.out("color").at(0, 1, 1), 0.58f, 1e-6f);
}

TEST(ClampedAccumulation, DefaultSevenBySevenWindowClippedAtBorder) {
    // Defaults (radius 3, k 1, alpha 0.2) on a 7x7 image: at the corner (0,0) the window is the
    // 4x4 top-left block. Block values: 1 at (0,0), 0 elsewhere -> mu = 1/16,
    // sigma^2 = 1/16 - 1/256 = 15/256, sigma = 0.2420615. History -1 is clamped to
    // mu - sigma = -0.1795615: out = 0.2 * 1 + 0.8 * -0.1795615 = 0.0563508.
    Image cur = grey(7, 7, 0.f);
    setGrey(cur, 0, 0, 1.f);
    Image hist = grey(7, 7, -1.f);
    auto h = PassHarness::make<ClampedAccumulationPass>({7, 7});
    h.bind("color", cur);
    h.bind("history", hist);
    h.run();
    EXPECT_NEAR(h.out("color").at(1, 0, 0), 0.0563508f, 1e-6f);
}

TEST(ClampedAccumulation, AlphaIsOneWhereProjectionFailed) {
    Image cur(8, 6, Format::Float3), hist = grey(8, 6, 5.f);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < cur.extent().pixels(); ++i) cur.channel(c)[i] = u(rng);
    Image len1(8, 6, Format::Float);
    len1.fill(3.f);
    len1.at(0, 2, 2) = 0.f;  // disoccluded
    len1.at(0, 5, 4) = std::numeric_limits<float>::quiet_NaN();
    auto h = PassHarness::make<ClampedAccumulationPass>({8, 6});
    h.bind("color", cur);
    h.bind("history", hist);
    h.bind("historyLength", len1);
    h.run();
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(h.out("color").at(c, 2, 2), cur.at(c, 2, 2));
        EXPECT_EQ(h.out("color").at(c, 5, 4), cur.at(c, 5, 4));
        // A valid pixel does use the (clamped) history.
        EXPECT_GT(std::fabs(h.out("color").at(c, 3, 3) - cur.at(c, 3, 3)), 1e-3f);
    }
    // No history bound at all (first frame): the current colour, exactly.
    auto first = PassHarness::make<ClampedAccumulationPass>({8, 6});
    first.bind("color", cur);
    first.run();
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < cur.extent().pixels(); ++i)
            ASSERT_EQ(first.out("color").channel(c)[i], cur.channel(c)[i]);
}

TEST(ClampedAccumulation, ConstantStaysConstantAndStaleHistoryIsRejected) {
    // sigma = 0 on a constant image: any history is clamped onto the constant.
    Image cur = grey(9, 9, 0.7f), hist = grey(9, 9, 100.f);
    auto h = PassHarness::make<ClampedAccumulationPass>({9, 9});
    h.bind("color", cur);
    h.bind("history", hist);
    h.run();
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < 81; ++i) ASSERT_NEAR(h.out("color").channel(c)[i], 0.7f, 1e-6f);
}

TEST(ClampedAccumulation, StiffInputsGiveFiniteOutput) {
    const float inf = std::numeric_limits<float>::infinity();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    Image cur = grey(10, 10, 0.5f), hist = grey(10, 10, 0.5f);
    setGrey(cur, 1, 1, nan);
    setGrey(cur, 5, 5, inf);
    setGrey(cur, 6, 5, -inf);
    setGrey(cur, 8, 2, 1e30f);
    setGrey(hist, 2, 2, nan);
    setGrey(hist, 3, 7, inf);
    setGrey(hist, 7, 7, -1e30f);
    auto h = PassHarness::make<ClampedAccumulationPass>({10, 10});
    h.bind("color", cur);
    h.bind("history", hist);
    h.run();
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < 100; ++i)
            ASSERT_TRUE(std::isfinite(h.out("color").channel(c)[i])) << i;
    // The NaN history pixel is treated as a failed projection.
    EXPECT_EQ(h.out("color").at(0, 2, 2), 0.5f);
}

TEST(ClampedAccumulation, OneAndTwoThreadsIdentical) {
    const Extent e{123, 77};
    Image cur(e, Format::Float3), hist(e, Format::Float3), len(e, Format::Float);
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(0.f, 2.f);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < e.pixels(); ++i) {
            cur.channel(c)[i] = u(rng);
            hist.channel(c)[i] = u(rng);
        }
    for (size_t i = 0; i < e.pixels(); ++i) len.channel(0)[i] = float(i % 5);
    auto h1 = PassHarness::make<ClampedAccumulationPass>(e, {}, 1);
    auto h2 = PassHarness::make<ClampedAccumulationPass>(e, {}, 2);
    for (auto* h : {&h1, &h2}) {
        h->bind("color", cur);
        h->bind("history", hist);
        h->bind("historyLength", len);
        h->run();
    }
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < e.pixels(); ++i)
            ASSERT_EQ(h1.out("color").channel(c)[i], h2.out("color").channel(c)[i]);
}

// A one-pixel black gap between lit walls, with a history equal to the current colour: the
// homework's box (7x7 mean +- sigma: 0.86 +- 0.35) excludes the gap's own 0 and lifts its
// history into a halo; with holdCurrent the box contains the current colour and the gap stays
// black.
TEST(ClampedAccumulation, HoldCurrentKeepsAHistoryThatEqualsTheCurrentColour) {
    Image cur = grey(12, 8, 1.f);
    for (int y = 0; y < 8; ++y)
        for (int c = 0; c < 3; ++c) cur.at(c, 5, y) = 0.f;
    auto run = [&](bool holdCurrent) {
        auto h =
            PassHarness::make<ClampedAccumulationPass>({12, 8}, {{"holdCurrent", holdCurrent}});
        h.bind("color", cur);
        h.bind("history", cur);  // the same image: a static scene
        h.run();
        return h.out("color").at(0, 5, 4);  // in the gap
    };
    EXPECT_GT(run(false), 0.3f);  // the homework's box: a halo (0.8 x 0.51)
    EXPECT_EQ(run(true), 0.f);
}
