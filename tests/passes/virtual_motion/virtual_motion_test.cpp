// VirtualMotion on a synthetic mirror floor: a camera panning (and moving) over the plane y = 0,
// which reflects a wall at z = -8. Every pixel's path length is traced as Cycles' Denoising
// Depth describes it (camera -> floor -> wall), so the test checks the pass against the
// geometry, not against its own formula: the virtual motion must send a reflection pixel to
// where the reflected wall point was seen last frame.
#include <denoise/TapsMask.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "VirtualMotionPass.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using kestrel::testing::PassHarness;

namespace {

constexpr int W = 64, H = 48;
constexpr double kWallZ = -8.0;

struct V3 {
    double x, y, z;
    V3 operator+(V3 o) const { return {x + o.x, y + o.y, z + o.z}; }
    V3 operator-(V3 o) const { return {x - o.x, y - o.y, z - o.z}; }
    V3 operator*(double s) const { return {x * s, y * s, z * s}; }
    double dot(V3 o) const { return x * o.x + y * o.y + z * o.z; }
    double norm() const { return std::sqrt(dot(*this)); }
};

/// A pinhole camera at `eye` turned by `yaw` about +Y and pitched down by `pitch` (radians),
/// 60 degrees horizontal field of view, OpenGL conventions as camera.json's.
struct Camera {
    V3 eye;
    double yaw, pitch;
    double tanX = std::tan(30.0 * M_PI / 180.0), tanY = tanX * H / W;
    V3 right() const { return {std::cos(yaw), 0, -std::sin(yaw)}; }
    V3 forward() const {
        return {-std::sin(yaw) * std::cos(pitch), -std::sin(pitch),
                -std::cos(yaw) * std::cos(pitch)};
    }
    V3 up() const {
        const V3 r = right(), f = forward();  // up = right x forward
        return {r.y * f.z - r.z * f.y, r.z * f.x - r.x * f.z, r.x * f.y - r.y * f.x};
    }
    Mat4 worldToCamera() const {
        const V3 r = right(), u = up(), b = forward() * -1.0;
        Mat4 m = Mat4::identity();
        const V3 rows[3] = {r, u, b};
        for (int i = 0; i < 3; ++i) {
            m.m[i][0] = float(rows[i].x), m.m[i][1] = float(rows[i].y);
            m.m[i][2] = float(rows[i].z), m.m[i][3] = float(-rows[i].dot(eye));
        }
        return m;
    }
    Mat4 worldToPixel() const {
        const double n = 0.1, f = 100.0;
        Mat4 p;
        p.m[0][0] = float(1.0 / tanX);
        p.m[1][1] = float(1.0 / tanY);
        p.m[2][2] = float((f + n) / (n - f));
        p.m[2][3] = float(2 * f * n / (n - f));
        p.m[3][2] = -1.f;
        Mat4 vp = Mat4::identity();
        vp.m[0][0] = W / 2.f, vp.m[0][3] = W / 2.f;
        vp.m[1][1] = -H / 2.f, vp.m[1][3] = H / 2.f;
        return vp * p * worldToCamera();
    }
    /// Unit world direction through pixel position (px, py).
    V3 ray(double px, double py) const {
        const double cx = (px / W * 2 - 1) * tanX, cy = (1 - py / H * 2) * tanY;
        const V3 d = right() * cx + up() * cy + forward();
        return d * (1.0 / d.norm());
    }
    /// Pixel position of world point p.
    void project(V3 p, double& px, double& py) const {
        const V3 d = p - eye;
        const double z = d.dot(forward());
        px = (d.dot(right()) / z / tanX + 1) / 2 * W;
        py = (1 - d.dot(up()) / z / tanY) / 2 * H;
    }
};

/// Camera -> floor (y = 0, a mirror) -> wall (z = kWallZ): the floor point, the wall point and
/// the path length; false where the ray misses the floor or its reflection misses the wall.
bool trace(const Camera& c, double px, double py, V3& floor, V3& wall, double& length) {
    const V3 d = c.ray(px, py);
    if (!(d.y < -1e-6)) return false;
    floor = c.eye + d * (-c.eye.y / d.y);
    const V3 r = {d.x, -d.y, d.z};
    if (!(r.z < -1e-6)) return false;
    const double t = (kWallZ - floor.z) / r.z;
    if (!(t > 0)) return false;
    wall = floor + r * t;
    length = (floor - c.eye).norm() + t;
    return true;
}

struct Frame {
    Image motion{W, H, Format::Float2}, reflection{W, H, Format::Float},
        pathLength{W, H, Format::Float};
};

/// The inputs the loader would give for camera `cur` after `prev`: surface (floor) motion, the
/// reflection mask and the path length.
Frame frameOf(const Camera& cur, const Camera& prev) {
    Frame f;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            V3 fl, wall;
            double L;
            const bool hit = trace(cur, x + 0.5, y + 0.5, fl, wall, L);
            double qx = x + 0.5, qy = y + 0.5;
            if (hit) prev.project(fl, qx, qy);
            f.motion.at(0, x, y) = float(qx - (x + 0.5));
            f.motion.at(1, x, y) = float(qy - (y + 0.5));
            f.reflection.at(0, x, y) = hit ? 1.f : 0.f;
            f.pathLength.at(0, x, y) = hit ? float(L) : 0.f;
        }
    return f;
}

const Camera kPrev{{0.0, 1.5, 0.0}, 0.0, 0.25};
const Camera kCur{{0.15, 1.5, -0.1}, 0.04, 0.25};  // panned 2.3 degrees, moved

PassHarness harness(const Frame& cur, const Frame& prev, bool withHistory = true) {
    auto h = PassHarness::make<VirtualMotionPass>({W, H});
    h.scene.hasCamera = h.previousScene.hasCamera = true;
    h.scene.worldToCamera = kCur.worldToCamera();
    h.scene.worldToPixel = kCur.worldToPixel();
    h.previousScene.worldToCamera = kPrev.worldToCamera();
    h.previousScene.worldToPixel = kPrev.worldToPixel();
    h.bind("motion", cur.motion.view());
    h.bind("reflection", cur.reflection.view());
    h.bind("pathLength", cur.pathLength.view());
    if (withHistory)
        h.bind("prevPathLength", prev.pathLength.view());
    else
        h.unbind("prevPathLength");
    h.useOutputs({"motion"});
    return h;
}

}  // namespace

// The virtual motion lands each reflection pixel on the pixel that showed the same wall point
// last frame (its virtual image below the floor is fixed); the floor's own motion does not.
TEST(VirtualMotion, MirrorFloorReflectionLandsWhereItWas) {
    const Frame cur = frameOf(kCur, kPrev), prev = frameOf(kPrev, kPrev);
    auto h = harness(cur, prev);
    h.run();
    int checked = 0;
    double worstSurface = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            V3 fl, wall;
            double L;
            if (!trace(kCur, x + 0.5, y + 0.5, fl, wall, L)) continue;
            const V3 image = {wall.x, -wall.y, wall.z};  // the wall point's mirror image
            double qx, qy;
            kPrev.project(image, qx, qy);
            if (qx < 1 || qy < 1 || qx > W - 1 || qy > H - 1) continue;  // was off screen
            // Where last frame showed that wall point (the same ray through the floor).
            V3 fl0, wall0;
            double L0;
            ASSERT_TRUE(trace(kPrev, qx, qy, fl0, wall0, L0));
            ASSERT_NEAR((wall0 - wall).norm(), 0.0, 1e-6);
            const float mx = h.out("motion").at(0, x, y), my = h.out("motion").at(1, x, y);
            EXPECT_NEAR(x + 0.5 + mx, qx, 2e-3) << x << "," << y;
            EXPECT_NEAR(y + 0.5 + my, qy, 2e-3) << x << "," << y;
            worstSurface =
                std::max(worstSurface, std::hypot(x + 0.5 + cur.motion.at(0, x, y) - qx,
                                                  y + 0.5 + cur.motion.at(1, x, y) - qy));
            ++checked;
        }
    EXPECT_GT(checked, W * H / 4);
    EXPECT_GT(worstSurface, 1.0);  // the floor's own motion misses the reflection
}

// The surface motion's taps pass on unchanged where the motion is the surface motion; a pixel
// given the virtual motion is marked untested, so the next Reprojection runs its own tests.
TEST(VirtualMotion, PassesTapsOnMarkingThePixelsItMoved) {
    const Frame cur = frameOf(kCur, kPrev), prev = frameOf(kPrev, kPrev);
    Image tapsIn({W, H}, Format::Int32);
    for (size_t i = 0; i < tapsIn.view().pixels(); ++i) tapsIn.view().ints()[i] = int32_t(i % 97);
    auto h = harness(cur, prev);
    h.bind("taps", tapsIn);
    h.useOutputs({"motion", "taps"});
    h.run();
    int moved = 0, kept = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * W + size_t(x);
            const bool same = h.out("motion").at(0, x, y) == cur.motion.at(0, x, y) &&
                              h.out("motion").at(1, x, y) == cur.motion.at(1, x, y);
            const int32_t t = h.out("taps").view().ints()[i];
            EXPECT_EQ(t, same ? tapsIn.view().ints()[i] : taps::kUntested) << x << "," << y;
            (same ? kept : moved)++;
        }
    EXPECT_GT(moved, W * H / 4);
    EXPECT_GT(kept, W * H / 8);  // the rows above the horizon see no floor
}

// A pixel the mask leaves out, or one whose virtual image disagrees with last frame's path
// length (a curved mirror, a moving reflected object), keeps its surface motion.
TEST(VirtualMotion, KeepsSurfaceMotionOffReflectionsAndWhereInconsistent) {
    Frame cur = frameOf(kCur, kPrev);
    const Frame prev = frameOf(kPrev, kPrev);
    const int x = W / 2, y = H - 4;
    ASSERT_EQ(cur.reflection.at(0, x, y), 1.f);
    cur.reflection.at(0, x, y) = 0.f;  // not a reflection
    Frame lying = frameOf(kCur, kPrev);
    for (int yy = 0; yy < H; ++yy)
        for (int xx = 0; xx < W; ++xx) lying.pathLength.at(0, xx, yy) *= 1.2f;
    for (const Frame* f : {&cur, &lying}) {
        auto h = harness(*f, prev);
        h.run();
        const int px = f == &cur ? x : x - 3;  // the lying frame: any reflection pixel
        EXPECT_EQ(h.out("motion").at(0, px, y), f->motion.at(0, px, y));
        EXPECT_EQ(h.out("motion").at(1, px, y), f->motion.at(1, px, y));
    }
    // Without the history test, the lying path length is taken (the test is what rejects it).
    auto h = harness(lying, prev, false);
    h.run();
    EXPECT_NE(h.out("motion").at(0, x - 3, y), lying.motion.at(0, x - 3, y));
}

// NaN, infinite, zero and negative path lengths, NaN masks and a missing previous camera give
// the surface motion; a NaN surface motion stays as it was (Reprojection reads it as unknown).
TEST(VirtualMotion, NonFiniteInputsGiveTheSurfaceMotion) {
    const float nan = std::numeric_limits<float>::quiet_NaN(),
                inf = std::numeric_limits<float>::infinity();
    Frame cur = frameOf(kCur, kPrev);
    const Frame prev = frameOf(kPrev, kPrev);
    const int y = H - 4;
    const float lengths[] = {nan, inf, -inf, 0.f, -2.f};
    for (int i = 0; i < 5; ++i) cur.pathLength.at(0, 10 + i, y) = lengths[i];
    cur.reflection.at(0, 20, y) = nan;
    cur.motion.at(0, 21, y) = nan;
    cur.motion.at(1, 21, y) = nan;
    // With and without the history test (without it nothing else rejects a zero length: the
    // eye's own position would be projected).
    for (bool withHistory : {true, false}) {
        auto g = harness(cur, prev, withHistory);
        g.run();
        for (int x : {10, 11, 12, 13, 14, 20}) {
            EXPECT_EQ(g.out("motion").at(0, x, y), cur.motion.at(0, x, y)) << x << withHistory;
            EXPECT_EQ(g.out("motion").at(1, x, y), cur.motion.at(1, x, y)) << x << withHistory;
        }
    }
    auto h = harness(cur, prev);
    h.run();
    // x = 21: the virtual motion does not need the surface motion, so it is still computed.
    EXPECT_TRUE(std::isfinite(h.out("motion").at(0, 21, y)));
    for (int yy = 0; yy < H; ++yy)
        for (int xx = 0; xx < W; ++xx)
            if (xx != 21 || yy != y) {
                ASSERT_TRUE(std::isfinite(h.out("motion").at(0, xx, yy)));
                ASSERT_TRUE(std::isfinite(h.out("motion").at(1, xx, yy)));
            }
    // No previous camera: the surface motion everywhere.
    auto first = harness(cur, prev);
    first.previousScene.hasCamera = false;
    first.run();
    for (int x = 0; x < W; ++x)
        EXPECT_EQ(first.out("motion").at(0, x, H - 10), cur.motion.at(0, x, H - 10)) << x;
}

// Where the scene has no reflection or pathLength the pass is left out at compile time: the
// motion forwarded, and the surface motion's taps passed on to the next Reprojection.
TEST(VirtualMotion, LeftOutWithoutReflectionOrPathLength) {
    struct Resolve final : ResolveContext {
        std::vector<std::string> bound;
        std::map<std::string, std::string> forwarded, absent;
        std::vector<std::string> notes;
        bool isBound(std::string_view in) const override {
            return std::find(bound.begin(), bound.end(), in) != bound.end();
        }
        void forward(std::string_view out, std::string_view in) override {
            forwarded[std::string(out)] = in;
        }
        void setAbsent(std::string_view out, std::string why) override {
            absent[std::string(out)] = why;
        }
        void note(std::string n) override { notes.push_back(n); }
        int64_t firstFrame() const override { return 0; }
        std::string_view passName() const override { return "virtualMotion"; }
    };
    VirtualMotionPass pass{kestrel::testing::makeParams(VirtualMotionPass::describe(), {})};
    Resolve noPath;
    noPath.bound = {"motion", "reflection", "taps"};
    pass.resolve(noPath);
    EXPECT_EQ(noPath.forwarded["motion"], "motion");
    EXPECT_EQ(noPath.forwarded["taps"], "taps");
    Resolve all;
    all.bound = {"motion", "reflection", "pathLength", "taps"};
    pass.resolve(all);
    EXPECT_TRUE(all.forwarded.empty());
    EXPECT_EQ(all.absent.count("taps"), 0u);  // computed: the taps with moved pixels marked
    Resolve noTaps;
    noTaps.bound = {"motion", "reflection", "pathLength"};
    pass.resolve(noTaps);
    EXPECT_EQ(noTaps.absent.count("taps"), 1u);
}
