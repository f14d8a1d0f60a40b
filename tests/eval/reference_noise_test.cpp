// The reference's own noise on flat pixels (eval/Regions.h: flat, ReferenceNoise), on synthetic
// frames whose noise is known.
#include <eval/Regions.h>
#include <gtest/gtest.h>
#include <scenegen/SceneGen.h>

#include <cmath>
#include <numbers>
#include <random>

#include "../GraphTestUtil.h"
#include "../TempDir.h"
#include "GBufferTestUtil.h"

using namespace kestrel;
using namespace kestrel::eval;

namespace {

constexpr int W = 96, H = 64;

/// One grey plane of object 1 facing the camera at depth 4, moving by (mx, my) px per frame.
GBuffer plane(float mx, float my) {
    return testutil::greySurface(W, H, 4.f, mx, my);
}

/// Display values: a lighting pattern fixed to the surface, seen `frame` frames after it was at
/// its origin (so moved by -frame x motion on screen: motion points to where a pixel was), plus
/// independent Gaussian noise of deviation sigma.
Image shaded(int frame, float mx, float my, float sigma, std::mt19937& rng, bool withPattern) {
    Image img(W, H, Format::Float3);
    std::normal_distribution<float> noise(0.f, sigma);
    for (int c = 0; c < 3; ++c)
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                // Surface coordinates: where this pixel was `frame` frames ago.
                const float u = float(x) + float(frame) * mx, v = float(y) + float(frame) * my;
                const float light =
                    withPattern ? 0.15f * std::sin(2.3f * u) * std::cos(1.7f * v) : 0.f;
                img.at(c, x, y) = 0.5f + 0.002f * u + light + noise(rng);
            }
    return img;
}

/// Mean reference noise estimated over frames 1..4 of a plane moving by (mx, my).
ReferenceNoise measure(float mx, float my, float sigma, bool withPattern, bool outputIsReference) {
    std::mt19937 rng(7);
    const GBuffer g = plane(mx, my);
    const RegionMasks masks = classifyRegions(g, &g);
    ReferenceNoise noise;
    DisplayFrame before;
    for (int f = 0; f < 5; ++f) {
        DisplayFrame now;
        now.ref = shaded(f, mx, my, sigma, rng, withPattern);
        now.out = outputIsReference ? shaded(f, mx, my, sigma, rng, withPattern)
                                    : shaded(f, mx, my, 0.f, rng, withPattern);
        if (f > 0) noise.add(now, before, g, g, masks[kFlat]);
        before = std::move(now);
    }
    return noise;
}

}  // namespace

TEST(Regions, FlatMeansOnePlaneWithOneAlbedo) {
    GBuffer g = plane(0.f, 0.f);
    // A crease at x = 40: the depth's slope changes (inverse depth no longer linear).
    for (int y = 0; y < H; ++y)
        for (int x = 40; x < W; ++x)
            g.depth[size_t(y) * W + size_t(x)] = 4.f + 0.2f * float(x - 40);
    g.albedoLum[size_t(20) * W + 20] = 0.45f;  // a texel 10% darker
    const RegionMasks m = classifyRegions(g, nullptr);
    const auto flat = [&](int x, int y) { return m[kFlat][size_t(y) * W + size_t(x)] != 0; };
    EXPECT_TRUE(flat(10, 10));
    EXPECT_FALSE(flat(0, 10));   // on the border: not every neighbour on screen
    EXPECT_FALSE(flat(40, 10));  // at the crease
    EXPECT_TRUE(flat(60, 10));   // on the second plane
    EXPECT_FALSE(flat(21, 21));  // next to the texel
    g.specularLum.assign(g.specularLum.size(), 0.1f);
    EXPECT_FALSE(classifyRegions(g, nullptr)[kFlat][size_t(10) * W + 10]);  // a little glossy
}

// E|n_t - n_t-1| for Gaussian noise of deviation s is 2 s / sqrt(pi), whatever the sub-pixel
// motion (the resampled frame's noise is smoother; the estimate scales for it).
TEST(ReferenceNoise, EstimatesTheChangeOfIndependentNoise) {
    const float sigma = 0.01f;
    const double expected = 2.0 * sigma / std::sqrt(std::numbers::pi);
    for (auto [mx, my] : {std::pair{0.f, 0.f}, {0.3f, -0.6f}, {-1.5f, 0.5f}}) {
        const ReferenceNoise n = measure(mx, my, sigma, false, false);
        ASSERT_GT(n.samples, 40000u) << mx << ", " << my;
        EXPECT_NEAR(n.floor(), expected, 0.03 * expected) << "motion " << mx << ", " << my;
        // The output is the noise-free image: its temporal instability is the reference's noise.
        EXPECT_NEAR(n.output(), expected, 0.03 * expected) << "motion " << mx << ", " << my;
    }
}

// Lighting detail fixed to the surface moves with it: following the motion vectors, it does not
// count as noise (a pixel-scale pattern of amplitude 0.15 against noise of 0.01). At whole-pixel
// motion the resampling is exact; at sub-pixel motion bilinear resampling smooths such detail and
// the rest reads as noise (Regions.h: ReferenceNoise says so).
TEST(ReferenceNoise, LightingThatMovesWithTheSurfaceIsNotNoise) {
    const float sigma = 0.01f;
    const double expected = 2.0 * sigma / std::sqrt(std::numbers::pi);
    const ReferenceNoise n = measure(-2.f, 1.f, sigma, true, false);
    ASSERT_GT(n.samples, 40000u);
    EXPECT_NEAR(n.floor(), expected, 0.03 * expected);
    // Another reference of the same noise as output: twice the variance of the change.
    const ReferenceNoise two = measure(-2.f, 1.f, sigma, true, true);
    EXPECT_NEAR(two.output() / two.floor(), std::sqrt(2.0), 0.05);

    RegionStats stats;  // reported beside the region table
    stats.noise = n;
    stats.temporalSamples[kAll] = n.samples;
    EXPECT_NE(formatRegionTable(stats).find("reference's own noise"), std::string::npos);
    EXPECT_DOUBLE_EQ(regionsToJson(stats)["referenceNoise"]["floor"].get<double>(), n.floor());
    stats.temporalSamples[kAll] = 200 * n.samples;  // on 0.5% of the frame: too few to tell
    EXPECT_EQ(formatRegionTable(stats).find("reference's own noise"), std::string::npos);
}

// Where the previous frame showed another surface under the footprint (another albedo: a
// disocclusion, an object passing), its change is not noise and is left out.
TEST(ReferenceNoise, OnlyWhereThePreviousFrameShowedTheSameSurface) {
    std::mt19937 rng(3);
    const GBuffer g = plane(0.5f, 0.f);
    GBuffer prev = plane(0.5f, 0.f);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W / 2; ++x) prev.albedoLum[size_t(y) * W + size_t(x)] = 0.2f;
    const DisplayFrame a{shaded(0, 0.5f, 0, 0.01f, rng, false),
                         shaded(0, 0.5f, 0, 0.01f, rng, false)};
    const DisplayFrame b{shaded(1, 0.5f, 0, 0.01f, rng, false),
                         shaded(1, 0.5f, 0, 0.01f, rng, false)};
    const std::vector<uint8_t> flat = classifyRegions(g, nullptr)[kFlat];
    ReferenceNoise same, changed;
    same.add(b, a, g, g, flat);
    changed.add(b, a, g, prev, flat);
    ASSERT_TRUE(changed.measured());
    // Only the right half: footprints reaching x < W/2 (or its 3x3 windows) saw another albedo.
    EXPECT_LT(changed.samples, same.samples * 55 / 100);
    EXPECT_GT(changed.samples, same.samples * 40 / 100);
}

// The loader's word on anti-aliasing decides whether compare measures the reference's noise: a
// pixel filter wider than a pixel correlates neighbours' noise, which the estimate cannot allow
// for.
TEST(ReferenceNoise, GBufferReaderTellsAnAntiAliasedRender) {
    for (const char* scene : {"street", "street-jittered"}) {
        scenegen::SceneOptions o = scenegen::zooScene(scene).options;
        o.width = 32;
        o.height = 24;
        o.frames = 1;
        o.referenceSpp = 2;
        const auto dir = testutil::processTempDir() / scene;
        scenegen::writeSequence(o, dir);
        GBufferReader reader(testutil::builtPlugins(), (dir / "noisy/frame_####.exr").string(),
                             o.firstFrame);
        EXPECT_EQ(reader.antiAliased(), std::string(scene) == "street-jittered") << scene;
    }
}

TEST(ReferenceNoise, NothingMeasuredWithoutMotionOrOnTexture) {
    std::mt19937 rng(1);
    GBuffer g = plane(0.f, 0.f);
    DisplayFrame a{shaded(0, 0, 0, 0.01f, rng, false), shaded(0, 0, 0, 0.01f, rng, false)};
    DisplayFrame b{shaded(1, 0, 0, 0.01f, rng, false), shaded(1, 0, 0, 0.01f, rng, false)};
    for (size_t i = 0; i < g.albedoLum.size(); ++i) g.albedoLum[i] = (i % 2) ? 0.2f : 0.8f;
    ReferenceNoise textured;
    textured.add(b, a, g, g, classifyRegions(g, &g)[kFlat]);
    EXPECT_FALSE(textured.measured());
    GBuffer still = plane(0.f, 0.f);
    still.motionX.clear();
    still.motionY.clear();
    ReferenceNoise noMotion;
    noMotion.add(b, a, still, still, classifyRegions(still, &still)[kFlat]);
    EXPECT_FALSE(noMotion.measured());
}
