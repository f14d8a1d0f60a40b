// ExrLoader on sequences written by the scene generator (src/scenegen): every output equals the
// generator's in-memory AOVs, in both the canonical and the GAMES202 layout.
#include <gtest/gtest.h>
#include <scenegen/SceneGen.h>

#include <algorithm>
#include <utility>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;
namespace sg = kestrel::scenegen;

namespace {
sg::SceneOptions smallScene(sg::SceneOptions::Layout layout) {
    sg::SceneOptions o;
    o.width = 24;
    o.height = 14;
    o.frames = 2;
    o.firstFrame = 1;
    o.referenceSpp = 1;
    o.threads = 1;
    o.layout = layout;
    return o;
}

void expectPlanes(const kestrel::Image& img, const float* const* planes, int channels, int n,
                  const char* what) {
    for (int c = 0; c < channels; ++c)
        for (int i = 0; i < n; ++i)
            ASSERT_EQ(img.channel(c)[i], planes[c][i])
                << what << " channel " << c << " pixel " << i;
}
}  // namespace

TEST(ExrLoaderScenegen, CanonicalSequenceLoadsAsGenerated) {
    TempDir tmp("sgcanon");
    auto opt = smallScene(sg::SceneOptions::Layout::Canonical);
    sg::writeSequence(opt, tmp.path);
    const sg::FrameAovs f = sg::renderFrame(opt, 2);
    auto h = PassHarness::make<ExrLoader>({1, 1},
                                          {{"path", (tmp.path / "noisy/frame_####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    for (const char* o : {"color", "albedo", "emission", "direct", "indirect", "normal", "depth",
                          "position", "motion", "objectId"})
        EXPECT_EQ(rc.absent.count(o), 0u) << o;
    h.useOutputs({"color", "albedo", "emission", "direct", "indirect", "normal", "depth",
                  "position", "motion", "objectId"});
    h.ctx.frameNumber = 2;
    h.run();
    const int n = f.width * f.height;
    auto p3 = [](const std::array<std::vector<float>, 3>& a) {
        return std::array<const float*, 3>{a[0].data(), a[1].data(), a[2].data()};
    };
    expectPlanes(h.out("color"), p3(f.color).data(), 3, n, "color");
    expectPlanes(h.out("albedo"), p3(f.albedo).data(), 3, n, "albedo");
    expectPlanes(h.out("emission"), p3(f.emission).data(), 3, n, "emission");
    expectPlanes(h.out("direct"), p3(f.direct).data(), 3, n, "direct");
    expectPlanes(h.out("indirect"), p3(f.indirect).data(), 3, n, "indirect");
    expectPlanes(h.out("normal"), p3(f.normal).data(), 3, n, "normal");
    expectPlanes(h.out("position"), p3(f.position).data(), 3, n, "position");
    const float* depth[] = {f.depth.data()};
    expectPlanes(h.out("depth"), depth, 1, n, "depth");
    const float* motion[] = {f.motion[0].data(), f.motion[1].data()};
    expectPlanes(h.out("motion"), motion, 2, n, "motion");
    for (int i = 0; i < n; ++i)
        ASSERT_EQ(h.out("objectId").view().ints()[i], f.objectId[size_t(i)]);
    ASSERT_TRUE(h.scene.hasCamera);
    EXPECT_EQ(h.scene.worldToPixel, f.worldToPixel);
    EXPECT_EQ(h.scene.worldToCamera, f.worldToCamera);
    ASSERT_EQ(h.scene.objectToWorld.size(), f.objectToWorld.size());
    for (const auto& [id, m] : f.objectToWorld) EXPECT_EQ(h.scene.objectToWorld.at(id), m);
}

TEST(ExrLoaderScenegen, Games202SequenceLoadsAsGenerated) {
    TempDir tmp("sg202");
    auto opt = smallScene(sg::SceneOptions::Layout::Games202);
    sg::writeSequence(opt, tmp.path);
    const sg::FrameAovs f = sg::renderFrame(opt, 2);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", tmp.path.string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    h.useOutputs({"color", "normal", "depth", "objectId"});
    h.ctx.frameNumber = 2;
    h.run();
    const int n = f.width * f.height;
    const float* color[] = {f.color[0].data(), f.color[1].data(), f.color[2].data()};
    expectPlanes(h.out("color"), color, 3, n, "color");
    for (int i = 0; i < n; ++i) {
        ASSERT_EQ(h.out("objectId").view().ints()[i], f.objectId[size_t(i)]) << i;
        // Background depth: the file's 0 becomes 1e10 again; elsewhere the generator's value.
        ASSERT_NEAR(h.out("depth").channel(0)[i], f.depth[size_t(i)], 1e-4f * f.depth[size_t(i)])
            << i;
    }
    ASSERT_TRUE(h.scene.hasCamera);
    // Converted to OpenGL (looks down -z): the same view matrix as the canonical files carry.
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            EXPECT_NEAR(h.scene.worldToCamera.m[r][c], f.worldToCamera.m[r][c], 1e-5f) << r << c;
}

// Point-sampled or anti-aliased, decided from the data (the files state no pixel filter): the
// zoo's street (every primary ray through the pixel centre) and street-jittered (a 1.5 px
// Blackman-Harris filter: each 1-spp sample at a random point of its footprint), each written
// small, no camera.json; the loader's decision (the antiAliased fact) must tell them apart.
TEST(ExrLoaderScenegen, PixelFilterIsMeasuredOnGeneratedStreets) {
    for (const auto& [name, antiAliased] :
         {std::pair{"street", "false"}, std::pair{"street-jittered", "true"}}) {
        TempDir tmp(std::string("sgjitter-") + name);
        sg::SceneOptions opt = sg::zooScene(name).options;
        opt.width = 64;
        opt.height = 40;
        opt.frames = 1;
        opt.referenceSpp = 1;
        opt.threads = 1;
        sg::writeSequence(opt, tmp.path);
        auto h = PassHarness::make<ExrLoader>(
            {1, 1}, {{"path", (tmp.path / "noisy/frame_####.exr").string()}});
        RecordingResolve rc(1);
        h.pass().resolve(rc);
        EXPECT_EQ(rc.facts["antiAliased"], antiAliased) << name;
        EXPECT_TRUE(std::any_of(rc.notes.begin(), rc.notes.end(), [](const std::string& n) {
            return n.find("render (depth jitter score") != std::string::npos;
        })) << name;
    }
}
