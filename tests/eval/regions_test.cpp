// Regions from the G-buffer (eval/Regions.h) and their error sums.
#include <eval/Regions.h>
#include <gtest/gtest.h>
#include <kestrel/Conventions.h>

#include "GBufferTestUtil.h"

using namespace kestrel;
using namespace kestrel::eval;

namespace {

constexpr int W = 8, H = 4;

/// A flat grey surface of object 1 at depth 5, no motion.
GBuffer surface() {
    return testutil::greySurface(W, H, 5.f);
}

size_t at(int x, int y) {
    return size_t(y) * W + size_t(x);
}

}  // namespace

TEST(Regions, EachRegionFromItsGBufferCue) {
    GBuffer g = surface();
    g.depth[at(0, 0)] = kBackgroundDepth;  // sky
    g.objectId[at(0, 0)] = kBackgroundId;
    g.emissionLum[at(7, 0)] = 4.f;   // emitter
    g.specularLum[at(7, 3)] = 0.9f;  // metal: specular brighter than diffuse
    g.albedoLum[at(4, 2)] = 0.05f;   // a dark texel on the grey surface
    RegionMasks m = classifyRegions(g, nullptr);
    EXPECT_TRUE(m[kBackground][at(0, 0)]);
    EXPECT_FALSE(m[kBackground][at(1, 0)]);
    EXPECT_TRUE(m[kEmissive][at(7, 0)]);
    EXPECT_FALSE(m[kTextured][at(7, 0)]);  // emitters are not texture
    EXPECT_TRUE(m[kGlossy][at(7, 3)]);
    EXPECT_FALSE(m[kGlossy][at(6, 3)]);
    EXPECT_TRUE(m[kTextured][at(4, 2)]);
    EXPECT_TRUE(m[kTextured][at(3, 1)]);   // its neighbours see the edge too
    EXPECT_FALSE(m[kTextured][at(1, 2)]);  // flat albedo
    for (size_t i = 0; i < m[kAll].size(); ++i)
        EXPECT_FALSE(m[kDisoccluded][i]);  // no frame before
    EXPECT_FALSE(m[kReflection][at(2, 2)]);  // no reflection output: none
}

// reflection: where the loader's reflection output is set (features through a mirror), never
// on the background.
TEST(Regions, ReflectionFromTheLoadersReflectionOutput) {
    GBuffer g = surface();
    g.reflection.assign(g.depth.size(), 0.f);
    g.reflection[at(3, 2)] = 1.f;
    g.reflection[at(0, 0)] = 1.f;
    g.depth[at(0, 0)] = kBackgroundDepth;
    g.objectId[at(0, 0)] = kBackgroundId;
    RegionMasks m = classifyRegions(g, nullptr);
    EXPECT_TRUE(m[kReflection][at(3, 2)]);
    EXPECT_FALSE(m[kReflection][at(2, 2)]);
    EXPECT_FALSE(m[kReflection][at(0, 0)]);
    EXPECT_STREQ(regionName(kReflection), "reflection");
}

TEST(Regions, DisoccludedWhereThePreviousFrameShowsAnotherSurface) {
    GBuffer prev = surface(), cur = surface();
    // Another object stood over (3..4, 1..2) last frame.
    for (int y = 1; y <= 2; ++y)
        for (int x = 3; x <= 4; ++x) prev.objectId[at(x, y)] = 2;
    cur.motionX[at(6, 1)] = -8.f;  // comes from off screen
    RegionMasks m = classifyRegions(cur, &prev);
    EXPECT_TRUE(m[kDisoccluded][at(6, 1)]);
    EXPECT_FALSE(m[kDisoccluded][at(6, 2)]);
    // (3, 1)'s bilinear footprint at (3.5, 1.5) is (3..4, 1..2): object 2 there before.
    EXPECT_TRUE(m[kDisoccluded][at(3, 1)]);
    EXPECT_FALSE(m[kDisoccluded][at(5, 2)]);
}

TEST(Regions, StatsCompareOutputAndInputPerRegion) {
    GBuffer g = surface();
    g.depth[at(0, 0)] = kBackgroundDepth;
    RegionMasks m = classifyRegions(g, nullptr);
    Image ref(W, H, Format::Float3), out(W, H, Format::Float3), in(W, H, Format::Float3);
    ref.fill(0.5f);
    out.fill(0.5f);
    in.fill(4.f);  // a noisy input everywhere
    for (int c = 0; c < 3; ++c) {
        in.at(c, 0, 0) = 0.5f;    // but exact on the sky
        out.at(c, 0, 0) = 0.f;    // where the output went black
        out.at(c, 5, 2) = 0.55f;  // and a small error on the surface
    }
    RegionStats s;
    s.add(out.view(), ref.view(), in.view(), m);
    s.add(out.view(), ref.view(), in.view(), m);
    ASSERT_TRUE(s.has(kBackground));
    EXPECT_FALSE(s.has(kEmissive));
    EXPECT_EQ(s.samples[kBackground], 6u);  // one pixel, three channels, two frames
    EXPECT_EQ(s.framesWith[kBackground], 2u);
    EXPECT_GT(s.ratio(kBackground), 1.0);  // worse than the input
    EXPECT_LT(s.ratio(kAll), 1.0);         // though better overall
    EXPECT_GT(s.outPsnr(kAll), s.inPsnr(kAll));
    EXPECT_TRUE(s.worseThanInput(kBackground));
    EXPECT_FALSE(s.worseThanInput(kAll));
    EXPECT_NE(formatRegionTable(s).find("worse than the input"), std::string::npos);
    EXPECT_EQ(regionsToJson(s)["background"]["frames"], 2);
    EXPECT_EQ(regionsToJson(s)["background"]["worseThanInput"], true);
}

// A region the output passes through unchanged up to float rounding (emission added back after
// filtering) is not reported worse than the input; an error of 0.005 in linear value is.
TEST(Regions, RoundingIsNotWorseThanTheInput) {
    RegionMasks m = classifyRegions(surface(), nullptr);
    Image ref(W, H, Format::Float3), in(W, H, Format::Float3), out(W, H, Format::Float3);
    ref.fill(0.5f);
    in.fill(0.6f);
    out.fill(0.600001f);  // 1e-6 above the input: rounding-level
    RegionStats s;
    s.add(out.view(), ref.view(), in.view(), m);
    EXPECT_GT(s.ratio(kAll), 1.0);
    EXPECT_FALSE(s.worseThanInput(kAll));
    EXPECT_EQ(formatRegionTable(s).find("worse than the input"), std::string::npos);
    out.fill(0.605f);
    RegionStats t;
    t.add(out.view(), ref.view(), in.view(), m);
    EXPECT_TRUE(t.worseThanInput(kAll));
}

// Temporal instability per region: a pixel whose output changes while the reference does not
// counts in its own region only; a change the reference makes too counts nowhere.
TEST(Regions, TemporalInstabilityIsMeasuredPerRegion) {
    GBuffer g = surface();
    g.depth[at(0, 0)] = kBackgroundDepth;
    const RegionMasks m = classifyRegions(g, nullptr);
    Image ref(W, H, Format::Float3), in(W, H, Format::Float3), out(W, H, Format::Float3);
    ref.fill(1.f);
    in.fill(1.f);
    out.fill(1.f);
    RegionStats s;
    const DisplayFrame first = s.add(out.view(), ref.view(), in.view(), m);
    EXPECT_FALSE(s.hasTemporal(kAll));                          // no frame before the first
    for (int c = 0; c < 3; ++c) out.at(c, 3, 1) = 3.f;          // one surface pixel brightens
    ref.fill(3.f);                                              // as the reference does everywhere,
    out.at(0, 0, 0) = out.at(1, 0, 0) = out.at(2, 0, 0) = 3.f;  // and the sky
    const DisplayFrame second =
        s.add(out.view(), ref.view(), in.view(), m, ToneMap::Reinhard, &first);
    ASSERT_TRUE(s.hasTemporal(kAll));
    EXPECT_EQ(s.temporalSamples[kBackground], 3u);
    EXPECT_DOUBLE_EQ(s.temporal(kBackground), 0.0);
    // 31 surface pixels: one changes as the reference does, 30 stay (each off by the change).
    const double change = toneMap(ToneMap::Reinhard, 3.f) - toneMap(ToneMap::Reinhard, 1.f);
    EXPECT_NEAR(s.temporal(kAll), 30.0 * change / 32.0, 1e-6);
    EXPECT_GT(s.temporal(kAll), s.temporal(kBackground));
    EXPECT_EQ(second.out.view().pixels(), size_t(W) * H);
    EXPECT_NEAR(regionsToJson(s)["all"]["temporal"].get<double>(), s.temporal(kAll), 1e-12);
    EXPECT_NE(formatRegionTable(s).find("temporal"), std::string::npos);
}
