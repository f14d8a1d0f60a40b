// Point-sampled or anti-aliased: the loader's compile-time decision (PixelJitter.h) and the
// jitteredAlbedo output it gates.
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfHeader.h>
#include <gtest/gtest.h>

#include <random>

#include "ExrLoader.h"
#include "PixelJitter.h"
#include "exr_test_util.h"
#include "kestrel/Conventions.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel::exr;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {

constexpr int W = 64, H = 48;

/// Planar depth of a tilted plane seen at (x + 0.5 + jx, y + 0.5 + jy): 1/z is linear in screen
/// position. `jitter`: the sub-pixel offsets' half-range (0: pixel centres).
std::vector<float> planeDepth(float jitter, uint32_t seed = 1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-jitter, jitter);
    std::vector<float> z(size_t(W) * H);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const float sx = float(x) + 0.5f + (jitter > 0 ? u(rng) : 0.f);
            const float sy = float(y) + 0.5f + (jitter > 0 ? u(rng) : 0.f);
            z[size_t(y) * W + size_t(x)] = 1.f / (0.05f + 0.002f * sx + 0.004f * sy);
        }
    return z;
}

Channels canonicalFrame(const std::vector<float>& depth) {
    Channels ch;
    for (const char* c : {"R", "G", "B"}) ch[c].assign(depth.size(), 0.5f);
    for (const char* c : {"albedo.R", "albedo.G", "albedo.B"}) ch[c].assign(depth.size(), 0.25f);
    ch["depth.Z"] = depth;
    return ch;
}

RecordingResolve resolveLoader(const TempDir& tmp, const Channels& ch, const Imf::Header* attrs,
                               const std::string& antiAliased = "auto") {
    writeExr(tmp.path / "f.0001.exr", Imath::Box2i({0, 0}, {W - 1, H - 1}), ch, {}, attrs);
    auto h = PassHarness::make<ExrLoader>(
        {1, 1}, {{"path", (tmp.path / "f.####.exr").string()}, {"antiAliased", antiAliased}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    return rc;
}

}  // namespace

TEST(PixelJitter, PixelCentresScoreNearZeroJitteredSamplesNearOne) {
    const auto centred = planeDepth(0.f), jittered = planeDepth(0.75f);
    const float c = depthJitterScore(centred.data(), W, H),
                j = depthJitterScore(jittered.data(), W, H);
    EXPECT_LT(c, 0.1f * kJitterThreshold) << c;
    EXPECT_GT(j, 10.f * kJitterThreshold) << j;
}

TEST(PixelJitter, BackgroundOnlyCannotTell) {
    std::vector<float> sky(size_t(W) * H, kestrel::kBackgroundDepth);
    EXPECT_EQ(depthJitterScore(sky.data(), W, H), 0.f);
}

TEST(PixelJitter, StatedFilterWinsOverTheMeasure) {
    EXPECT_TRUE(decideAntiAliasing(1.5f, std::nullopt).antiAliased);
    EXPECT_FALSE(decideAntiAliasing(0.01f, 0.9f).antiAliased);
    EXPECT_TRUE(decideAntiAliasing(std::nullopt, 0.9f).antiAliased);
    EXPECT_FALSE(decideAntiAliasing(std::nullopt, 1e-5f).antiAliased);
    EXPECT_FALSE(decideAntiAliasing(std::nullopt, std::nullopt).antiAliased);
}

TEST(PixelJitter, LoaderOffersJitteredAlbedoOnlyForAntiAliasedRenders) {
    TempDir tmp("jitter");
    // Point-sampled depth, nothing stated: absent, with the measured reason.
    auto rc = resolveLoader(tmp, canonicalFrame(planeDepth(0.f)), nullptr);
    ASSERT_EQ(rc.absent.count("jitteredAlbedo"), 1u);
    EXPECT_NE(rc.absent["jitteredAlbedo"].find("point-sampled render (depth jitter score"),
              std::string::npos)
        << rc.absent["jitteredAlbedo"];
    // Jittered depth: present.
    rc = resolveLoader(tmp, canonicalFrame(planeDepth(0.75f)), nullptr);
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 0u);
    // A stated 1.5 px filter decides even over centred depth; the parameter over both.
    Imf::Header attrs;
    attrs.insert("kestrel.pixelFilterWidth", Imf::FloatAttribute(1.5f));
    rc = resolveLoader(tmp, canonicalFrame(planeDepth(0.f)), &attrs);
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 0u);
    rc = resolveLoader(tmp, canonicalFrame(planeDepth(0.f)), &attrs, "false");
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 1u);
    rc = resolveLoader(tmp, canonicalFrame(planeDepth(0.f)), nullptr, "true");
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 0u);
    // Without albedo there is nothing to offer.
    Channels noAlbedo = canonicalFrame(planeDepth(0.75f));
    for (const char* c : {"albedo.R", "albedo.G", "albedo.B"}) noAlbedo.erase(c);
    rc = resolveLoader(tmp, noAlbedo, nullptr);
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 1u);
    // The decision itself is a scene fact (TAA's onlyAntiAliased reads it), with or without an
    // albedo.
    EXPECT_EQ(rc.facts["antiAliased"], "true");
    rc = resolveLoader(tmp, canonicalFrame(planeDepth(0.f)), nullptr);
    EXPECT_EQ(rc.facts["antiAliased"], "false");
}

// A Blender render that states no pixel filter (no camera.json) is measured: samples off pixel
// centres decide anti-aliased from the data. Centred samples cannot tell (Cycles centres its first
// sample with any filter: blender-street's 0.01 and 1.5 px renders agree to 3e-7 in depth), so
// Blender's default 1.5 px filter is taken and the log says so with the score. The parameter
// still decides.
TEST(PixelJitter, BlenderWithoutAStatedFilterIsMeasuredElseTakesBlendersDefault) {
    TempDir tmp("jitter-blender");
    auto blenderFrame = [](const std::vector<float>& depth) {
        Channels ch;
        for (const char* c : {"R", "G", "B", "A"})
            ch[std::string("ViewLayer.Combined.") + c].assign(depth.size(), 0.5f);
        for (const char* c : {"R", "G", "B"})
            ch[std::string("ViewLayer.Denoising Albedo.") + c].assign(depth.size(), 0.25f);
        ch["ViewLayer.Depth.Z"] = depth;
        return ch;
    };
    auto noted = [](const RecordingResolve& rc, const std::string& what) {
        return std::any_of(rc.notes.begin(), rc.notes.end(),
                           [&](const std::string& n) { return n.find(what) != std::string::npos; });
    };
    auto rc = resolveLoader(tmp, blenderFrame(planeDepth(0.75f)), nullptr);
    EXPECT_EQ(rc.facts["antiAliased"], "true");
    EXPECT_TRUE(noted(rc, "anti-aliased render (depth jitter score"))
        << testing::PrintToString(rc.notes);
    EXPECT_FALSE(noted(rc, "assumed"));
    rc = resolveLoader(tmp, blenderFrame(planeDepth(0.f)), nullptr);
    EXPECT_EQ(rc.facts["antiAliased"], "true");
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 0u);
    EXPECT_TRUE(noted(rc, "Blender's default 1.5 px pixel filter (depth jitter score"))
        << testing::PrintToString(rc.notes);
    rc = resolveLoader(tmp, blenderFrame(planeDepth(0.75f)), nullptr, "false");
    EXPECT_EQ(rc.facts["antiAliased"], "false");
}

// The diffuse/specular split's albedos are averaged like the single albedo: each jittered*
// output is present exactly where its albedo is and the render is anti-aliased.
TEST(PixelJitter, SplitAlbedosFollowTheSameDecision) {
    TempDir tmp("jitter-split");
    Channels split = canonicalFrame(planeDepth(0.75f));
    for (const char* c : {"diffuseAlbedo.R", "diffuseAlbedo.G", "diffuseAlbedo.B"})
        split[c].assign(size_t(W) * H, 0.5f);
    auto rc = resolveLoader(tmp, split, nullptr);
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 0u);
    EXPECT_EQ(rc.absent.count("jitteredDiffuseAlbedo"), 0u);
    ASSERT_EQ(rc.absent.count("jitteredSpecularAlbedo"), 1u);  // no specularAlbedo
    EXPECT_NE(rc.absent["jitteredSpecularAlbedo"].find("no specularAlbedo"), std::string::npos)
        << rc.absent["jitteredSpecularAlbedo"];
    rc = resolveLoader(tmp, split, nullptr, "false");
    EXPECT_EQ(rc.absent.count("jitteredDiffuseAlbedo"), 1u);
    // The split's albedo without a single albedo still decides, and is offered.
    for (const char* c : {"albedo.R", "albedo.G", "albedo.B"}) split.erase(c);
    rc = resolveLoader(tmp, split, nullptr);
    EXPECT_EQ(rc.absent.count("jitteredAlbedo"), 1u);
    EXPECT_EQ(rc.absent.count("jitteredDiffuseAlbedo"), 0u);
}

// A jittered* output the channels parameter sets keeps what it was set to, whatever the
// decision; one it leaves out stays out.
TEST(PixelJitter, ChannelsOverrideOfAJitteredAlbedoIsKept) {
    TempDir tmp("jitter-override");
    writeExr(tmp.path / "f.0001.exr", Imath::Box2i({0, 0}, {W - 1, H - 1}),
             canonicalFrame(planeDepth(0.f)), {}, nullptr);
    auto resolveWith = [&](const std::string& channels) {
        auto h = PassHarness::make<ExrLoader>(
            {1, 1}, {{"path", (tmp.path / "f.####.exr").string()}, {"channels", channels}});
        RecordingResolve rc(1);
        h.pass().resolve(rc);
        return rc;
    };
    // Point-sampled, yet the override offers it.
    EXPECT_EQ(resolveWith("jitteredDiffuseAlbedo=albedo").absent.count("jitteredDiffuseAlbedo"),
              0u);
    EXPECT_EQ(resolveWith("jitteredAlbedo=").absent.count("jitteredAlbedo"), 1u);
}

TEST(PixelJitter, JitteredAlbedoHoldsTheAlbedo) {
    TempDir tmp("jitter-values");
    Imf::Header attrs;
    attrs.insert("kestrel.pixelFilterWidth", Imf::FloatAttribute(2.f));
    writeExr(tmp.path / "f.0001.exr", Imath::Box2i({0, 0}, {W - 1, H - 1}),
             canonicalFrame(planeDepth(0.f)), {}, &attrs);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
    h.useOutputs({"albedo", "jitteredAlbedo"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("jitteredAlbedo").at(1, 3, 2), 0.25f);
    EXPECT_EQ(h.out("albedo").at(1, 3, 2), 0.25f);
}
