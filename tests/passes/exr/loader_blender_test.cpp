// ExrLoader on the real Blender Cycles sample (../shared/data/blender-sample-room).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {
struct Blender : ::testing::Test {
    std::string dir;
    void SetUp() override {
        dir = sharedData("blender-sample-room");
        if (dir.empty()) GTEST_SKIP() << "../shared/data/blender-sample-room not present";
    }
    std::string pattern() const { return dir + "/noisy/frame_####.exr"; }
    std::string frame(int f) const {
        char b[32];
        std::snprintf(b, sizeof b, "/noisy/frame_%04d.exr", f);
        return dir + b;
    }
    PassHarness load(int frameNumber, std::vector<std::string> outputs = {}) {
        auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", pattern()}});
        if (!outputs.empty()) h.useOutputs(outputs);
        h.ctx.frameNumber = frameNumber;
        h.run();
        return h;
    }
};
}  // namespace

TEST_F(Blender, ResolveFindsEveryOutputAndTheCamera) {
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", pattern()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    // The sample is point-sampled (camera.json: 0.01 px filter), so its albedo needs no averaging.
    for (const char* o : {"jitteredAlbedo", "jitteredDiffuseAlbedo", "jitteredSpecularAlbedo"}) {
        EXPECT_EQ(rc.absent[o], "point-sampled render (the source states a 0.01 px pixel filter)");
        rc.absent.erase(o);
    }
    EXPECT_TRUE(rc.absent.empty()) << rc.absent.begin()->first << ": " << rc.absent.begin()->second;
    std::string notes;
    for (auto& n : rc.notes) notes += n + "\n";
    EXPECT_NE(notes.find("layout blender"), std::string::npos) << notes;
    EXPECT_NE(notes.find("camera.json"), std::string::npos) << notes;
    EXPECT_NE(notes.find("direct = ViewLayer.DiffDir*ViewLayer.DiffCol + ViewLayer.GlossDir*"),
              std::string::npos)
        << notes;
}

TEST_F(Blender, PixelsMatchOpenExrAndConventions) {
    auto h = load(3);
    const auto& color = h.out("color");
    ASSERT_EQ(color.width(), 320);
    ASSERT_EQ(color.height(), 180);
    auto R = readChannel(frame(3), "ViewLayer.Combined.R");
    auto vy = readChannel(frame(3), "ViewLayer.Vector.Y");
    auto vx = readChannel(frame(3), "ViewLayer.Vector.X");
    auto index = readChannel(frame(3), "ViewLayer.IndexOB.X");
    auto depth = readChannel(frame(3), "ViewLayer.Depth.Z");
    auto diffCol = readChannel(frame(3), "ViewLayer.DiffCol.G");
    size_t i = 90 * 320 + 160;
    EXPECT_EQ(color.at(0, 160, 90), R[i]);
    EXPECT_EQ(h.out("albedo").at(1, 160, 90), diffCol[i]);
    EXPECT_EQ(h.out("depth").at(0, 160, 90), depth[i]);
    int moving = 0, background = 0;
    for (int y = 0; y < 180; ++y)
        for (int x = 0; x < 320; ++x) {
            size_t k = size_t(y) * 320 + size_t(x);
            // Blender's Vector y points up; ours points down.
            ASSERT_EQ(h.out("motion").at(0, x, y), vx[k]);
            ASSERT_EQ(h.out("motion").at(1, x, y), -vy[k]);
            moving += std::fabs(vy[k]) > 0.1f;
            int32_t id = h.out("objectId").atInt(x, y);
            ASSERT_EQ(id, index[k] == 0.f ? -1 : int32_t(index[k]));
            background += id == -1;
        }
    EXPECT_GT(moving, 1000);  // the camera dollies in: real motion to check the sign on
    EXPECT_GE(background, 0);
}

TEST_F(Blender, SplitsSumToCombinedToFloatPrecision) {
    // Combined = diffuse + specular + emission = direct + indirect + emission (data/README.md).
    auto h = load(5);
    const auto &c = h.out("color"), &e = h.out("emission"), &d = h.out("diffuse"),
               &s = h.out("specular"), &di = h.out("direct"), &in = h.out("indirect");
    double worst1 = 0, worst2 = 0;
    for (int ch = 0; ch < 3; ++ch)
        for (int y = 0; y < 180; ++y)
            for (int x = 0; x < 320; ++x) {
                double ref = c.at(ch, x, y), scale = 1e-3 + std::fabs(ref);
                worst1 = std::max(
                    worst1,
                    std::fabs(d.at(ch, x, y) + s.at(ch, x, y) + e.at(ch, x, y) - ref) / scale);
                worst2 = std::max(
                    worst2,
                    std::fabs(di.at(ch, x, y) + in.at(ch, x, y) + e.at(ch, x, y) - ref) / scale);
            }
    std::printf(
        "[ measured ] worst relative sum error %.2e (diffuse+specular), %.2e (direct+indirect)\n",
        worst1, worst2);
    // Measured: 3e-7 relative (float rounding of the sums).
    EXPECT_LT(worst1, 1e-5);
    EXPECT_LT(worst2, 1e-5);
}

TEST_F(Blender, CameraProjectsPositionsToTheirPixelCentres) {
    auto h = load(4, {"position", "depth", "objectId"});
    ASSERT_TRUE(h.scene.hasCamera);
    EXPECT_EQ(h.scene.objectToWorld.size(), 11u);
    const auto &p = h.out("position"), &z = h.out("depth");
    double worst = 0, worstZ = 0;
    int n = 0;
    for (int y = 0; y < 180; y += 7)
        for (int x = 0; x < 320; x += 7) {
            if (h.out("objectId").atInt(x, y) < 0) {
                EXPECT_EQ(z.at(0, x, y), kestrel::kBackgroundDepth);
                continue;
            }
            auto q =
                h.scene.worldToPixel.transformPoint({p.at(0, x, y), p.at(1, x, y), p.at(2, x, y)});
            worst = std::max({worst, std::fabs(double(q.x / q.w) - (x + 0.5)),
                              std::fabs(double(q.y / q.w) - (y + 0.5))});
            auto cam =
                h.scene.worldToCamera.transformPoint({p.at(0, x, y), p.at(1, x, y), p.at(2, x, y)});
            worstZ = std::max(worstZ, double(std::fabs(-cam.z - z.at(0, x, y)) / z.at(0, x, y)));
            worstZ = std::max(worstZ, double(std::fabs(q.w - z.at(0, x, y)) / z.at(0, x, y)));
            ++n;
        }
    std::printf("[ measured ] worst reprojection %.4f px, depth vs w %.2e relative\n", worst,
                worstZ);
    EXPECT_GT(n, 500);
    // Measured 0.0001 px (0.01-px pixel filter: rays through pixel centres) and 1e-7.
    EXPECT_LT(worst, 0.01);
    EXPECT_LT(worstZ, 1e-4);  // w of the projection is the planar depth
}

TEST_F(Blender, ReadsOnlyConsumedChannels) {
    auto* loader = static_cast<ExrLoader*>(nullptr);
    auto h = load(1, {"depth"});
    loader = static_cast<ExrLoader*>(&h.pass());
    EXPECT_EQ(loader->channelsRead(), std::vector<std::string>{"ViewLayer.Depth.Z"});
    auto h2 = load(1, {"direct", "albedo"});
    loader = static_cast<ExrLoader*>(&h2.pass());
    // DiffDir, DiffCol, GlossDir, GlossCol: 12 channels; albedo reuses DiffCol.
    EXPECT_EQ(loader->channelsRead().size(), 12u);
}

TEST_F(Blender, ChannelsOverrideAndCameraParameter) {
    auto h = PassHarness::make<ExrLoader>(
        {1, 1}, {{"path", pattern()},
                 {"channels", "albedo=ViewLayer.Denoising Albedo,emission=ViewLayer.Emit,motion="},
                 {"camera", dir + "/camera.json"}});
    RecordingResolve rc(2);
    h.pass().resolve(rc);
    ASSERT_EQ(rc.absent.count("motion"), 1u);
    h.useOutputs({"albedo", "emission"});
    h.ctx.frameNumber = 2;
    h.run();
    auto a = readChannel(frame(2), "ViewLayer.Denoising Albedo.B");
    EXPECT_EQ(h.out("albedo").at(2, 10, 170), a[170 * 320 + 10]);
    auto* loader = static_cast<ExrLoader*>(&h.pass());
    EXPECT_EQ(loader->channelsRead().size(), 6u);
}

TEST_F(Blender, ReadSpeedMatchesPlainOpenExr) {
    // Every output of 4 frames through the loader versus OpenEXR reading all 47 channels of the
    // same frames directly: the loader's conversions must not cost more than the decoding.
    const int frames = 4;
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", pattern()}}, 2);
    h.ctx.frameNumber = 1;
    h.run();  // warm-up: layout probe, camera.json, first file-cache misses
    size_t fileBytes = 0;
    auto t0 = std::chrono::steady_clock::now();
    for (int f = 2; f < 2 + frames; ++f) {
        h.run();
        fileBytes += std::filesystem::file_size(frame(f));
    }
    double loader = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    t0 = std::chrono::steady_clock::now();
    for (int f = 2; f < 2 + frames; ++f) readAllChannels(frame(f));
    double plain = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    size_t decoded =
        static_cast<ExrLoader&>(h.pass()).channelsRead().size() * 320 * 180 * 4 * frames;
    std::printf(
        "[ measured ] loader %.1f ms/frame (%.0f MB/s decoded, %.0f MB/s of file); plain "
        "OpenEXR, all 47 channels: %.1f ms/frame\n",
        loader / frames * 1e3, decoded / loader / 1e6, fileBytes / loader / 1e6,
        plain / frames * 1e3);
    // Measured on a loaded 2-core machine: loader 224 ms/frame, plain 320 ms/frame.
    EXPECT_LT(loader, 1.5 * plain + 0.02 * frames);
}
