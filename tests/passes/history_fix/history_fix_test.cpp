// HistoryFix: a pixel with no history takes its neighbours on the same surface (never across an
// object or a depth edge, nor from taps facing away; on depth alone where the normals isolate
// it), one with a short history keeps a growing share of its own colour, a pixel with a history
// passes unchanged, non-finite inputs give finite outputs, and the result does not depend on the
// thread count.
#include <gtest/gtest.h>

#include <cmath>

#include "../SvgfTestImages.h"
#include "HistoryFixPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {

struct Frame {
    Image color, length, depth, normal, id;
};

/// A flat wall at depth 5 facing the camera, colour 1 except a black pixel at (3, 3).
Frame wall(float centreLength, float othersLength) {
    Frame f{
        constant(7, 7, Format::Float3, 1.f),
        scalar(7, 7, [&](int x, int y) { return x == 3 && y == 3 ? centreLength : othersLength; }),
        constant(7, 7, Format::Float, 5.f), normals(7, 7, 0.f, 0.f, 1.f),
        ids(7, 7, [](int, int) { return 1; })};
    for (int c = 0; c < 3; ++c) f.color.at(c, 3, 3) = 0.f;
    return f;
}

PassHarness run(const Frame& f, int threads = 1) {
    auto h = PassHarness::make<HistoryFixPass>(f.color.extent(), {}, threads);
    h.bind("color", f.color);
    h.bind("historyLength", f.length);
    h.bind("depth", f.depth);
    h.bind("normal", f.normal);
    h.bind("objectId", f.id);
    h.run();
    return h;
}

}  // namespace

// The speckle the pass exists for: a black 1-spp sample with no history among filled neighbours.
TEST(HistoryFix, PixelWithoutHistoryTakesItsNeighbours) {
    auto h = run(wall(1.f, 8.f));
    // Neighbours weigh by their history (8 each) against the centre's 1: close to 1.
    EXPECT_GT(h.out("color").at(0, 3, 3), 0.9f);
    EXPECT_EQ(h.out("color").at(0, 2, 3), 1.f);  // long histories pass unchanged
}

TEST(HistoryFix, PixelWithAHistoryPassesUnchanged) {
    auto h = run(wall(8.f, 8.f));
    EXPECT_EQ(h.out("color").at(0, 3, 3), 0.f);
}

// Between no history and `frames` (4) the pixel keeps a share of its own colour that grows
// with its history, (hl - 1) / 3 of it at hl = 2 and 3, the rest filled from the 3x3 binomial
// footprint (the 5x5 is for pixels with no history). A step (all fill up to 2.5 frames, none
// after) blurred two-frame-old pixels as much as new ones (frame 2 of every zoo scene lost
// 0.3 dB) and left a three-frame-old black pixel black.
TEST(HistoryFix, OwnColourShareGrowsWithTheHistory) {
    for (float hl : {2.f, 3.f}) {
        const float own = (hl - 1.f) / 3.f;
        // The fill: 8 neighbours (binomial weights summing to 3/4, history 8) of colour 1
        // against the black centre (weight 1/4, history hl).
        const float neighbours = 0.75f * 8.f, fill = neighbours / (neighbours + 0.25f * hl);
        const float got = run(wall(hl, 8.f)).out("color").at(0, 3, 3);
        EXPECT_NEAR(got, (1.f - own) * fill, 1e-4f) << "historyLength " << hl;
    }
}

TEST(HistoryFix, NeverTakesAnotherObjectOrSurface) {
    Frame f = wall(1.f, 8.f);
    for (int y = 0; y < 7; ++y)
        for (int x = 0; x < 7; ++x)
            if (x != 3 || y != 3) f.id.atInt(x, y) = 2;
    EXPECT_EQ(run(f).out("color").at(0, 3, 3), 0.f);
    Frame g = wall(1.f, 8.f);
    for (int y = 0; y < 7; ++y)
        for (int x = 0; x < 7; ++x)
            if (x != 3 || y != 3) g.depth.at(0, x, y) = 9.f;  // the centre in front of a wall
    EXPECT_EQ(run(g).out("color").at(0, 3, 3), 0.f);
    Frame r = wall(1.f, 8.f);
    for (int y = 0; y < 7; ++y)
        for (int x = 0; x < 7; ++x)
            if (x != 3 || y != 3) r.normal.at(2, x, y) = -1.f;  // facing away: a mirror's sky
    EXPECT_EQ(run(r).out("color").at(0, 3, 3), 0.f);
}

// A pixel whose neighbours all fail the normal weight (Cycles' Denoising Normal follows each
// sample through a window: this one saw the reflected ground, its neighbours the reflected wall
// across the street) is filled on depth and id alone instead of keeping its black 1-spp sample,
// which A-Trous' normal test would isolate as well (a speckle).
TEST(HistoryFix, PixelIsolatedByItsNormalIsFilledOnItsPlane) {
    Frame f = wall(1.f, 8.f);
    f.normal.at(1, 3, 3) = 1.f;  // the centre's normal (0, 1, 0): perpendicular to the others'
    f.normal.at(2, 3, 3) = 0.f;
    EXPECT_GT(run(f).out("color").at(0, 3, 3), 0.9f);
    // With a history it keeps its colour as before.
    Frame g = wall(8.f, 8.f);
    g.normal.at(1, 3, 3) = 1.f;
    g.normal.at(2, 3, 3) = 0.f;
    EXPECT_EQ(run(g).out("color").at(0, 3, 3), 0.f);
}

TEST(HistoryFix, NonFiniteInputsGiveFiniteOutputs) {
    Frame f = wall(1.f, 1.f);
    f.color.at(0, 2, 3) = NAN;
    f.color.at(1, 4, 3) = INFINITY;
    f.length.at(0, 3, 2) = NAN;
    f.depth.at(0, 3, 4) = NAN;
    f.normal.at(0, 2, 2) = INFINITY;
    auto h = run(f);
    for (int c = 0; c < 3; ++c)
        for (int y = 0; y < 7; ++y)
            for (int x = 0; x < 7; ++x) EXPECT_TRUE(std::isfinite(h.out("color").at(c, x, y)));
}

TEST(HistoryFix, IdenticalWithOneAndTwoThreads) {
    Frame f{grey(40, 90, [](int x, int y) { return hash01(x, y) > 0.7f ? 0.f : hash01(x, y, 1); }),
            scalar(40, 90, [](int x, int y) { return std::floor(hash01(x, y, 2) * 6.f); }),
            scalar(40, 90, [](int x, int y) { return 3.f + 0.01f * float(x + y); }),
            normals(40, 90, 0.f, 0.f, 1.f), ids(40, 90, [](int x, int) { return x / 13; })};
    auto a = run(f, 1), b = run(f, 2);
    for (int c = 0; c < 3; ++c)
        for (int y = 0; y < 90; ++y)
            for (int x = 0; x < 40; ++x)
                ASSERT_EQ(a.out("color").at(c, x, y), b.out("color").at(c, x, y));
}
