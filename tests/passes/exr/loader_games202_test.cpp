// ExrLoader on the real GAMES202 homework data (../shared/data/games202-box).
#include <gtest/gtest.h>

#include <cmath>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {
struct Games202 : ::testing::Test {
    std::string dir;
    void SetUp() override {
        dir = sharedData("games202-box");
        if (dir.empty()) GTEST_SKIP() << "../shared/data/games202-box not present";
    }
};
}  // namespace

TEST_F(Games202, FolderPathResolvesLayoutAndAbsentOutputs) {
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", dir}});
    RecordingResolve rc(0);
    h.pass().resolve(rc);
    for (const char* o : {"albedo", "emission", "motion", "direct", "diffuse"}) {
        ASSERT_EQ(rc.absent.count(o), 1u) << o;
        EXPECT_NE(rc.absent[o].find("layout games202"), std::string::npos) << rc.absent[o];
    }
    for (const char* o : {"color", "normal", "position", "depth", "objectId"})
        EXPECT_EQ(rc.absent.count(o), 0u) << o;
    EXPECT_EQ(h.pass().availableFrames(), (std::vector<int64_t>{0, 1, 2, 3, 4, 5, 6, 7}));
}

TEST_F(Games202, PixelsDepthBackgroundIdsAndMatrices) {
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", dir + "/beauty_%d.exr"}});
    h.useOutputs({"color", "normal", "position", "depth", "objectId"});
    h.ctx.frameNumber = 2;
    h.run();
    ASSERT_EQ(h.out("color").width(), 512);
    auto R = readChannel(dir + "/beauty_2.exr", "R");
    auto B = readChannel(dir + "/beauty_2.exr", "B");
    auto Z = readChannel(dir + "/depth_2.exr", "Y");
    auto id = readChannel(dir + "/ID_2.exr", "Y");
    ASSERT_TRUE(h.scene.hasCamera);
    int bg = 0, fg = 0;
    double worst = 0, worstZ = 0;
    for (int y = 0; y < 512; ++y)
        for (int x = 0; x < 512; ++x) {
            size_t k = size_t(y) * 512 + size_t(x);
            ASSERT_EQ(h.out("color").at(0, x, y), R[k]);
            ASSERT_EQ(h.out("color").at(2, x, y), B[k]);
            int32_t oid = h.out("objectId").atInt(x, y);
            ASSERT_EQ(oid, int32_t(id[k]));
            if (oid < 0) {
                ++bg;
                ASSERT_EQ(h.out("depth").at(0, x, y), kestrel::kBackgroundDepth);
                continue;
            }
            ++fg;
            ASSERT_EQ(h.out("depth").at(0, x, y), Z[k]);
            if ((x | y) % 8) continue;
            const auto& p = h.out("position");
            // Object space of this object round-trips to the same pixel (matrix_i.mat).
            auto q =
                h.scene.worldToPixel.transformPoint({p.at(0, x, y), p.at(1, x, y), p.at(2, x, y)});
            auto cam =
                h.scene.worldToCamera.transformPoint({p.at(0, x, y), p.at(1, x, y), p.at(2, x, y)});
            worstZ =
                std::max(worstZ, std::fabs(double(-cam.z) - Z[k]) / Z[k]);  // OpenGL: depth = -z
            worst = std::max({worst, std::fabs(double(q.x / q.w) - (x + 0.5)),
                              std::fabs(double(q.y / q.w) - (y + 0.5))});
        }
    std::printf("[ measured ] worst reprojection %.4f px, camera depth %.2e relative\n", worst,
                worstZ);
    EXPECT_GT(bg, 0);
    EXPECT_GT(fg, 1000);
    EXPECT_EQ(h.scene.objectToWorld.size(), 7u);
    // Measured 0.0000 px and ~1e-7: positions are at pixel centres.
    EXPECT_LT(worst, 0.01);
    EXPECT_LT(worstZ, 1e-4);
}
