#include <gtest/gtest.h>

#include <limits>
#include <map>
#include <string>
#include <tuple>

#include "../FactResolve.h"
#include "../SameBits.h"
#include "../SvgfTestImages.h"
#include "ReprojectionPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {
constexpr int W = 10, H = 6;

/// A fronto-parallel plane at depth 10 seen by a pinhole camera (focal length 10 px, looking
/// down -Z) that moved by +2 world units along X since the last frame: every point now at
/// pixel x was at pixel x + 2 (motion (+2, 0)).
struct Frames {
    Image depth = constant(W, H, Format::Float, 10.f), normal = normals(W, H, 0, 0, 1);
    Image ids = svgftest::ids(W, H, [](int, int) { return 3; });
    Image prevDepth = constant(W, H, Format::Float, 10.f), prevNormal = normals(W, H, 0, 0, 1);
    Image prevIds = svgftest::ids(W, H, [](int, int) { return 3; });
    Image prevColor = grey(W, H, [](int x, int y) { return float(x + 100 * y); });
    Image prevMoments = Image(W, H, Format::Float2);
    Image prevLength = constant(W, H, Format::Float, 5.f);
    Image motion = Image(W, H, Format::Float2);
    Image position = Image(W, H, Format::Float3);
    Frames() {
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                prevMoments.at(0, x, y) = float(x);
                prevMoments.at(1, x, y) = float(y);
                motion.at(0, x, y) = 2.f;
                // World point seen at pixel (x, y) by the current camera at X = 2.
                position.at(0, x, y) = (float(x) + 0.5f - W / 2.f) + 2.f;
                position.at(1, x, y) = -(float(y) + 0.5f - H / 2.f);
                position.at(2, x, y) = -10.f;
            }
    }
};

Mat4 pinhole(float camX) {
    // pixel = (f X_c / -Z_c + W/2, -f Y_c / -Z_c + H/2), f = 10, camera at (camX, 0, 0).
    Mat4 view = Mat4::identity();
    view.m[0][3] = -camX;
    Mat4 proj{};
    proj.m[0] = {10.f, 0.f, -W / 2.f, 0.f};
    proj.m[1] = {0.f, -10.f, -H / 2.f, 0.f};
    proj.m[2] = {0.f, 0.f, 1.f, 0.f};
    proj.m[3] = {0.f, 0.f, -1.f, 0.f};
    return proj * view;
}

void setCameras(PassHarness& h, float cur, float prev) {
    for (auto [scene, x] : {std::pair{&h.scene, cur}, std::pair{&h.previousScene, prev}}) {
        scene->hasCamera = true;
        scene->worldToCamera = Mat4::identity();
        scene->worldToCamera.m[0][3] = -x;
        scene->worldToPixel = pinhole(x);
    }
}

PassHarness make(const Frames& f, bool useMotion, std::map<std::string, ParamValue> p = {},
                 int threads = 1) {
    auto h = PassHarness::make<ReprojectionPass>({W, H}, p, threads);
    h.bind("depth", f.depth);
    h.bind("normal", f.normal);
    h.bind("objectId", f.ids);
    if (useMotion)
        h.bind("motion", f.motion);
    else
        h.bind("position", f.position);
    h.bind("prevDepth", f.prevDepth);
    h.bind("prevNormal", f.prevNormal);
    h.bind("prevObjectId", f.prevIds);
    h.bind("prevColor", f.prevColor);
    h.bind("prevMoments", f.prevMoments);
    h.bind("prevHistoryLength", f.prevLength);
    setCameras(h, 2.f, 0.f);
    return h;
}
}  // namespace

TEST(Reprojection, CameraTranslationLandsOnExactPixels) {
    Frames f;
    for (bool useMotion : {true, false}) {
        auto h = make(f, useMotion);
        h.run();
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                SCOPED_TRACE(::testing::Message()
                             << (useMotion ? "motion" : "matrices") << " x=" << x << " y=" << y);
                if (x + 2 < W) {
                    EXPECT_NEAR(h.out("color").at(0, x, y), float(x + 2 + 100 * y), 1e-3f);
                    EXPECT_NEAR(h.out("moments").at(0, x, y), float(x + 2), 1e-4f);
                    EXPECT_NEAR(h.out("moments").at(1, x, y), float(y), 1e-4f);
                    EXPECT_NEAR(h.out("historyLength").at(0, x, y), 5.f, 1e-5f);
                } else if (x + 2 == W) {
                    // Lands just off screen: the 3x3 fallback averages the last column's
                    // rows y-1..y+1 that exist.
                    float sum = 0, n = 0;
                    for (int r = std::max(0, y - 1); r <= std::min(H - 1, y + 1); ++r, ++n)
                        sum += float(W - 1 + 100 * r);
                    EXPECT_NEAR(h.out("color").at(0, x, y), sum / n, 1e-3f);
                } else {  // came from outside the previous frame
                    EXPECT_EQ(h.out("historyLength").at(0, x, y), 0.f);
                    EXPECT_EQ(h.out("color").at(0, x, y), 0.f);
                }
            }
    }
}

TEST(Reprojection, DisocclusionResetsHistoryLength) {
    Frames f;
    // Last frame a near object (depth 2, id 7) covered previous columns 3..7, rows 1..4: the
    // plane behind it, visible now at columns 1..5, was hidden.
    for (int y = 1; y <= 4; ++y)
        for (int x = 3; x <= 7; ++x) {
            f.prevDepth.at(0, x, y) = 2.f;
            f.prevIds.atInt(x, y) = 7;
        }
    auto h = make(f, true);
    h.run();
    // Pixel (3, 2) maps to (5, 2): its 2x2 and 3x3 neighbourhoods are all occluder.
    EXPECT_EQ(h.out("historyLength").at(0, 3, 2), 0.f);
    EXPECT_EQ(h.out("historyLength").at(0, 3, 3), 0.f);
    // Untouched pixels keep their history.
    EXPECT_NEAR(h.out("historyLength").at(0, 0, 0), 5.f, 1e-5f);
    // Edge pixel (0, 2) -> (2, 2): exact tap consistent.
    EXPECT_NEAR(h.out("color").at(0, 0, 2), 2.f + 200.f, 1e-3f);

    // Depth alone (same ids) also rejects: |10 - 2| / (0 + 0.01) >> 10.
    for (int y = 1; y <= 4; ++y)
        for (int x = 3; x <= 7; ++x) f.prevIds.atInt(x, y) = 3;
    auto h2 = make(f, true);
    h2.run();
    EXPECT_EQ(h2.out("historyLength").at(0, 3, 2), 0.f);
}

TEST(Reprojection, WithoutGeometryTestsOnlyIdsAndScreenBoundsReject) {
    // Last frame a jittered G-buffer saw another depth and normal (columns 3..7, rows 1..4)
    // on the same object: with geometryTests off the history is kept there (TAA on anti-aliased
    // renders); a tap on another object or off screen is still rejected.
    Frames f;
    for (int y = 1; y <= 4; ++y)
        for (int x = 3; x <= 7; ++x) {
            f.prevDepth.at(0, x, y) = 2.f;
            f.prevNormal.at(0, x, y) = 1.f;
            f.prevNormal.at(2, x, y) = 0.f;
        }
    f.prevIds.atInt(9, 5) = 7;
    auto tested = make(f, true);
    tested.run();
    EXPECT_EQ(tested.out("historyLength").at(0, 3, 2), 0.f);  // the tests reject it
    auto h = make(f, true, {{"geometryTests", false}});
    h.run();
    for (int y = 1; y <= 4; ++y)
        for (int x = 1; x <= 5; ++x) {  // reads previous columns 3..7
            SCOPED_TRACE(::testing::Message() << "x=" << x << " y=" << y);
            EXPECT_NEAR(h.out("historyLength").at(0, x, y), 5.f, 1e-5f);
            EXPECT_NEAR(h.out("color").at(0, x, y), float(x + 2 + 100 * y), 1e-3f);
        }
    EXPECT_EQ(h.out("historyLength").at(0, 9, 2), 0.f);  // came from off screen
    // (7, 5) -> (9, 5), another object: the 2x2 tap and most of the 3x3 fallback are rejected,
    // and the fallback's taps on object 3 are all that is averaged.
    EXPECT_NEAR(h.out("color").at(0, 7, 5), (9.f + 400.f + 8.f + 400.f + 8.f + 500.f) / 3.f, 1e-3f);
}

// Depth stored as half (the loader's depthPrecision fact, 2^-10) steps by 0.5 at 1000: a still
// surface differs from last frame's by such a step, which the default test (10 x (fwidth +
// 0.01) on a flat surface) took for a disocclusion; with the fact it keeps its history.
TEST(Reprojection, HalfDepthStepsAreNotDisocclusions) {
    Frames f;
    f.depth = constant(W, H, Format::Float, 1000.f);
    f.prevDepth = constant(W, H, Format::Float, 1000.5f);
    // The same depth test with and without the precision slack (no camera model: a uniform
    // change of depth would fit a camera moving back).
    const std::map<std::string, ParamValue> noModel{{"depthPrediction", std::string("none")}};
    auto plain = make(f, true, noModel);
    plain.run();
    EXPECT_EQ(plain.out("historyLength").at(0, 3, 2), 0.f);
    auto half = make(f, true, noModel);
    FactResolve facts(kDepthPrecisionFact, "0.0009765625");
    half.pass().resolve(facts);
    half.run();
    EXPECT_NEAR(half.out("historyLength").at(0, 3, 2), 5.f, 1e-5f);
    // The widened test still rejects: beyond depthThreshold (10) times 2 steps (+ 0.01) = 19.6.
    f.prevDepth = constant(W, H, Format::Float, 1020.f);
    auto far = make(f, true, noModel);
    far.pass().resolve(facts);
    far.run();
    EXPECT_EQ(far.out("historyLength").at(0, 3, 2), 0.f);
}

// A background pixel among surface ones (a jittered render's sample that missed a thin object)
// has no depth slope: it matches only the background, so it takes no surface history. With the
// slope to its neighbours (1e10) every tap would pass, and the sky would darken.
TEST(Reprojection, IsolatedBackgroundPixelTakesNoSurfaceHistory) {
    Frames f;
    f.depth.at(0, 3, 2) = 1e10f;
    for (int c = 0; c < 3; ++c) f.normal.at(c, 3, 2) = 0.f;  // Blender's background normal
    auto h = make(f, true);
    h.run();
    EXPECT_EQ(h.out("historyLength").at(0, 3, 2), 0.f);
    EXPECT_NEAR(h.out("historyLength").at(0, 4, 2), 5.f, 1e-5f);  // its neighbours keep theirs
}

// Unknown motion (NaN: the loader's mark for a Blender background without camera.json) is a
// disocclusion: no history is reused there.
TEST(Reprojection, UnknownMotionIsADisocclusion) {
    Frames f;
    f.motion.at(0, 3, 2) = f.motion.at(1, 3, 2) = std::numeric_limits<float>::quiet_NaN();
    auto h = make(f, true);
    h.run();
    EXPECT_EQ(h.out("historyLength").at(0, 3, 2), 0.f);
    EXPECT_NEAR(h.out("historyLength").at(0, 4, 2), 5.f, 1e-5f);
}

TEST(Reprojection, HalfPixelMotionBlendsBilinearly) {
    Frames f;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) f.motion.at(0, x, y) = 0.5f;
    auto h = make(f, true);
    h.run();
    EXPECT_NEAR(h.out("color").at(0, 4, 2), 4.5f + 200.f, 1e-3f);
    // Catmull-Rom on a linear ramp reproduces the ramp too, and never overshoots a step.
    auto c = make(f, true, {{"filter", std::string("catmullrom")}});
    c.run();
    EXPECT_NEAR(c.out("color").at(0, 4, 2), 4.5f + 200.f, 1e-3f);
    f.prevColor = grey(W, H, [](int x, int) { return x < 5 ? 0.f : 1.f; });
    auto step = make(f, true, {{"filter", std::string("catmullrom")}});
    step.run();
    for (int x = 0; x < W; ++x) {
        EXPECT_GE(step.out("color").at(0, x, 2), 0.f);
        EXPECT_LE(step.out("color").at(0, x, 2), 1.f);
    }
}

TEST(Reprojection, ResampleBlurFollowsTheSubPixelOffset) {
    // resampleBlur = 2 (fx (1 - fx) + fy (1 - fy)): 0 on a pixel centre, 1 midway between four,
    // for both filters, in the tap kernel (interior) and the per-pixel path (border) alike.
    for (const char* filter : {"bilinear", "catmullrom"}) {
        for (auto [mx, my, expected] :
             {std::tuple{2.f, 0.f, 0.f}, std::tuple{1.5f, 0.5f, 1.f},
              std::tuple{2.25f, 0.f, 0.375f}, std::tuple{0.75f, -0.25f, 0.75f}}) {
            Frames f;
            for (int y = 0; y < H; ++y)
                for (int x = 0; x < W; ++x) {
                    f.motion.at(0, x, y) = mx;
                    f.motion.at(1, x, y) = my;
                }
            auto h = make(f, true, {{"filter", std::string(filter)}});
            h.run();
            for (auto [x, y] : {std::pair{3, 2}, std::pair{0, 0}, std::pair{4, 3}})
                EXPECT_NEAR(h.out("resampleBlur").at(0, x, y), expected, 1e-5f)
                    << filter << " motion " << mx << "," << my << " at " << x << "," << y;
        }
    }
    // Disoccluded (every tap and the 3x3 fallback on another object): 0, like historyLength.
    Frames f;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) f.motion.at(0, x, y) = 0.5f;
    for (int y = 1; y <= 4; ++y)
        for (int x = 2; x <= 7; ++x) f.prevIds.atInt(x, y) = 7;
    auto h = make(f, true, {{"filter", std::string("catmullrom")}});
    h.run();
    EXPECT_EQ(h.out("historyLength").at(0, 3, 2), 0.f);
    EXPECT_EQ(h.out("resampleBlur").at(0, 3, 2), 0.f);
    // Pixel (1, 2) maps to x = 2.0, midway between columns 1 and 2: column 2 is on the occluder,
    // column 1 survives; the offset, not the surviving taps, sets the blur (fx 0.5, fy 0).
    EXPECT_NEAR(h.out("resampleBlur").at(0, 1, 2), 0.5f, 1e-5f);
}

TEST(Reprojection, InvalidHistoryGivesZeros) {
    Frames f;
    auto h = make(f, true);
    h.bind("prevColor", f.prevColor, false);
    h.bind("prevMoments", f.prevMoments, false);
    h.run();
    for (int x = 0; x < W; ++x) {
        EXPECT_EQ(h.out("historyLength").at(0, x, 1), 0.f);
        EXPECT_EQ(h.out("color").at(0, x, 1), 0.f);
    }
}

TEST(Reprojection, NonFiniteInputsGiveFiniteOutputs) {
    Frames f;
    f.motion.at(0, 1, 1) = NAN;
    f.motion.at(1, 2, 1) = INFINITY;
    f.motion.at(0, 3, 1) = -1e30f;
    f.depth.at(0, 4, 4) = NAN;
    f.normal.at(0, 5, 5) = NAN;
    f.prevColor.at(0, 4, 2) = NAN;
    f.prevMoments.at(1, 5, 3) = INFINITY;
    f.prevDepth.at(0, 6, 0) = NAN;
    auto h = make(f, true);
    h.run();
    for (const char* o : {"color", "moments", "historyLength"})
        EXPECT_TRUE(allFinite(h.out(o))) << o;
    EXPECT_EQ(h.out("historyLength").at(0, 1, 1), 0.f);  // NaN motion: disoccluded
}

TEST(Reprojection, IdenticalWithOneAndTwoThreads) {
    Frames f;
    const int w = W, hgt = H;
    for (int y = 0; y < hgt; ++y)
        for (int x = 0; x < w; ++x) {
            f.motion.at(0, x, y) = 3.f * hash01(x, y) - 1.5f;
            f.motion.at(1, x, y) = 3.f * hash01(x, y, 1) - 1.5f;
        }
    auto a = make(f, true, {}, 1), b = make(f, true, {}, 2);
    a.run();
    b.run();
    for (const char* o : {"color", "moments", "historyLength"})
        EXPECT_TRUE(sameBits(a.out(o), b.out(o))) << o;
}
