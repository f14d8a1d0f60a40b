// The camera model behind the depth test on the motion-vector path (DepthChangeModel.h): fitted
// to a moving pinhole camera's correspondences, and what it changes in the pass (a dollying
// camera keeps the history of a wall facing it).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "../SvgfTestImages.h"
#include "DepthChangeModel.h"
#include "ReprojectionPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {
constexpr int W = 96, H = 64;
constexpr float kFocal = 80.f;  // pixels

/// Two frames of a pinhole camera (looking down -Z) over a scene whose depth at pixel (x, y) is
/// `depthAt`: the camera moved forward by `dolly` and turned by `yaw` radians about Y since the
/// last frame. Motion vectors and last frame's depths are exact for every static point.
struct CameraPair {
    Image depth = Image(W, H, Format::Float), prevDepth = Image(W, H, Format::Float);
    Image motion = Image(W, H, Format::Float2);
    CameraPair(float dolly, float yaw, float (*depthAt)(int, int)) {
        const float cs = std::cos(yaw), sn = std::sin(yaw);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const float u = (float(x) + 0.5f - W / 2.f) / kFocal;
                const float v = (float(y) + 0.5f - H / 2.f) / kFocal;
                const float z = depthAt(x, y);
                // Point in the current camera (depth z along the view axis), then in the last
                // frame's camera: behind by `dolly`, rotated by -yaw.
                const float px = u * z, py = v * z, pz = z + dolly;
                const float qx = cs * px - sn * pz, qz = sn * px + cs * pz;
                depth.at(0, x, y) = z;
                motion.at(0, x, y) = (qx / qz * kFocal + W / 2.f) - (float(x) + 0.5f);
                motion.at(1, x, y) = (py / qz * kFocal + H / 2.f) - (float(y) + 0.5f);
                // Last frame's depth where the point was (the same surface, continuous).
                const int tx = int(std::floor(float(x) + 0.5f + motion.at(0, x, y)));
                const int ty = int(std::floor(float(y) + 0.5f + motion.at(1, x, y)));
                if (tx >= 0 && ty >= 0 && tx < W && ty < H) prevDepth.at(0, tx, ty) = qz;
            }
        // Pixels no point landed on keep their nearest written neighbour along the row.
        for (int y = 0; y < H; ++y)
            for (int x = 1; x < W; ++x)
                if (prevDepth.at(0, x, y) == 0.f) prevDepth.at(0, x, y) = prevDepth.at(0, x - 1, y);
    }
    DepthChangeInputs inputs() const {
        return {W,
                H,
                depth.channel(0),
                motion.channel(0),
                motion.channel(1),
                nullptr,
                prevDepth.channel(0),
                nullptr,
                10.f,
                0.f};
    }
};

float wall(int, int) {
    return 10.f;
}
/// A street: the ground 1.5 below the camera up to a wall at depth 20.
float street(int, int y) {
    const float v = (float(y) + 0.5f - H / 2.f) / kFocal;
    return v > 1.5f / 20.f ? 1.5f / v : 20.f;
}
}  // namespace

TEST(DepthChangeModel, StillCameraKeepsTheIdentity) {
    CameraPair still(0.f, 0.f, street);
    // Stored depths differ a little from frame to frame (precision, jitter): a fit to them is
    // not exactly the identity, and passes no more of the test than the identity does.
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            still.prevDepth.at(0, x, y) *= 1.f + 1e-3f * float((x * 5 + y * 3) % 7 - 3) / 3.f;
    EXPECT_TRUE(fitDepthChange(still.inputs()).isIdentity());
}

TEST(DepthChangeModel, PredictsADollyingAndTurningCamera) {
    CameraPair pair(0.6f, 0.02f, street);
    // A fifth of last frame's depths are another surface (disocclusions, a moving object).
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if ((x * 7 + y * 13) % 5 == 0) pair.prevDepth.at(0, x, y) *= 0.5f;
    const DepthChangeModel m = fitDepthChange(pair.inputs());
    ASSERT_FALSE(m.isIdentity());
    int checked = 0;
    for (int y = 2; y < H - 2; y += 3)
        for (int x = 2; x < W - 2; x += 3) {
            const float z = pair.depth.at(0, x, y);
            const float u = (float(x) + 0.5f - W / 2.f) / kFocal;
            const float truth = std::sin(0.02f) * u * z + std::cos(0.02f) * (z + 0.6f);
            // Within a tenth of the depth test's tolerance there (10 (fwidth + 0.01)).
            const float fw = std::fabs(pair.depth.at(0, x + 1, y) - z) +
                             std::fabs(pair.depth.at(0, x, y + 1) - z);
            EXPECT_NEAR(m.predict(z, x, m.rowTerm(y)), truth, (fw + 0.01f)) << x << "," << y;
            ++checked;
        }
    EXPECT_GT(checked, 400);
}

// A wall facing a camera that moves towards it by 0.5 per frame: every pixel is 0.5 nearer than
// last frame, 50x the depth test's tolerance (threshold 10 x 0.01 on a flat wall). Predicted by
// the camera model, the history stays; compared with this frame's depth (SVGF's test) it is
// rejected everywhere.
TEST(Reprojection, DollyingCameraKeepsTheHistoryOfAWallFacingIt) {
    CameraPair pair(0.5f, 0.f, wall);
    const Image normal = normals(W, H, 0, 0, 1), prevColor = constant(W, H, Format::Float3, 1.f),
                prevLength = constant(W, H, Format::Float, 6.f);
    auto run = [&](const std::string& prediction) {
        auto h = PassHarness::make<ReprojectionPass>({W, H}, {{"depthPrediction", prediction}}, 1);
        h.bind("depth", pair.depth);
        h.bind("normal", normal);
        h.bind("motion", pair.motion);
        h.bind("prevDepth", pair.prevDepth);
        h.bind("prevNormal", normal);
        h.bind("prevColor", prevColor);
        h.bind("prevHistoryLength", prevLength);
        h.run();
        int kept = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) kept += h.out("historyLength").at(0, x, y) > 0.f;
        return kept;
    };
    EXPECT_GT(run("camera"), W * H * 9 / 10);
    EXPECT_EQ(run("none"), 0);
}
