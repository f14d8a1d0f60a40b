// Positions from depth and background motion from the cameras (passes/exr/Unproject.h), on an
// analytic pinhole camera: a 60 degree field of view, 64x48 pixels.
#include "Unproject.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace kestrel;
using kestrel::exr::skyMotionRows;
using kestrel::exr::unprojectRows;

namespace {

constexpr int W = 64, H = 48;
constexpr double kPi = 3.14159265358979323846;

/// Camera to pixel coordinates (OpenGL perspective, then the viewport: x right, y down).
Mat4 cameraToPixel() {
    const double f = 1.0 / std::tan(kPi / 6.0), aspect = double(W) / H, n = 0.1, fa = 100.0;
    Mat4 proj;  // OpenGL clip from camera
    proj.m[0][0] = float(f / aspect);
    proj.m[1][1] = float(f);
    proj.m[2][2] = float((fa + n) / (n - fa));
    proj.m[2][3] = float(2 * fa * n / (n - fa));
    proj.m[3][2] = -1.f;
    Mat4 viewport = Mat4::identity();  // pixel = ((x/w + 1) W/2, (1 - y/w) H/2)
    viewport.m[0][0] = W / 2.f;
    viewport.m[0][3] = W / 2.f;
    viewport.m[1][1] = -H / 2.f;
    viewport.m[1][3] = H / 2.f;
    return viewport * proj;
}

/// Camera to world: a turn of `yaw` radians to the left (about +y), at `eye`.
Mat4 cameraToWorld(double yaw, Vec3 eye = {}) {
    Mat4 m = Mat4::identity();
    m.m[0][0] = float(std::cos(yaw));
    m.m[0][2] = float(std::sin(yaw));
    m.m[2][0] = float(-std::sin(yaw));
    m.m[2][2] = float(std::cos(yaw));
    m.m[0][3] = eye.x;
    m.m[1][3] = eye.y;
    m.m[2][3] = eye.z;
    return m;
}

}  // namespace

// A pixel's position at planar depth d projects back onto its centre at w = d; at a ray length
// the point lies that far from the eye.
TEST(Unproject, PositionsProjectBackToTheirPixelCentres) {
    const Mat4 c2w = cameraToWorld(0.3, {1.f, 2.f, 3.f});
    const Mat4 w2p = cameraToPixel() * *inverse(c2w);
    std::vector<float> depth(size_t(W) * H, 7.5f), x(depth.size()), y(x.size()), z(x.size());
    depth[5] = 0.f;    // background (Denoising Depth)
    depth[6] = 1e10f;  // background (Depth.Z)
    for (bool rayLength : {false, true}) {
        unprojectRows(cameraToPixel(), c2w, depth.data(), rayLength, {x.data(), y.data(), z.data()},
                      W, 0, H);
        for (int py = 0; py < H; py += 5)
            for (int px = 0; px < W; px += 3) {
                const size_t i = size_t(py) * W + size_t(px);
                if (i == 5 || i == 6) continue;
                const Vec4 q = w2p.transformPoint({x[i], y[i], z[i]});
                EXPECT_NEAR(q.x / q.w, px + 0.5, 1e-3) << px << "," << py;
                EXPECT_NEAR(q.y / q.w, py + 0.5, 1e-3) << px << "," << py;
                const double dx = x[i] - 1.0, dy = y[i] - 2.0, dz = z[i] - 3.0;
                const double dist = std::sqrt(dx * dx + dy * dy + dz * dz);
                EXPECT_NEAR(rayLength ? dist : q.w, 7.5, 1e-3) << px << "," << py;
            }
        for (size_t i : {size_t(5), size_t(6)}) EXPECT_EQ(x[i] + y[i] + z[i], 0.f);
    }
}

// The camera turned left by 2 degrees since the previous frame: what is straight ahead now was
// f tan(2 deg) pixels right of the centre then (f = H / 2 / tan(30 deg)), so the background
// moves by that to the previous frame; surface pixels keep their motion.
TEST(Unproject, SkyMotionFollowsTheCameraRotation) {
    const double yaw = 2.0 * kPi / 180.0;
    const Mat4 c2w = cameraToWorld(0.0), prevW2P = cameraToPixel() * *inverse(cameraToWorld(yaw));
    std::vector<float> depth(size_t(W) * H, 1e10f), mx(depth.size(), 0.f), my(mx.size(), 0.f);
    const size_t surface = size_t(10) * W + 10;
    depth[surface] = 4.f;
    mx[surface] = 0.25f;
    skyMotionRows(cameraToPixel(), c2w, prevW2P, depth.data(), {mx.data(), my.data()}, W, 0, H);
    const size_t centre = size_t(H / 2) * W + W / 2;  // pixel (32, 24): its centre is 0.5 off
    const double f = H / 2.0 / std::tan(kPi / 6.0);
    EXPECT_NEAR(mx[centre], f * std::tan(yaw), 0.05);
    EXPECT_NEAR(my[centre], 0.0, 0.05);
    EXPECT_GT(mx[centre], 0.f);
    EXPECT_EQ(mx[surface], 0.25f);
    EXPECT_EQ(my[surface], 0.f);
}

// Normals from positions: a plane facing the camera at planar depth 5 (left half) and a floor
// seen from above it (right half, a depth edge between them): each pixel gets its own plane's
// normal, turned to the eye, also beside the edge (the neighbour closer in depth is used);
// background stays 0.
TEST(Unproject, NormalsFromPositionsFollowEachPlaneUpToTheDepthEdge) {
    const Mat4 c2w = cameraToWorld(0.0, {0.f, 1.f, 0.f});
    std::vector<float> depth(size_t(W) * H);
    std::vector<float> p[3], n[3];
    for (auto& v : p) v.resize(depth.size());
    for (auto& v : n) v.resize(depth.size());
    const Mat4 c2p = cameraToPixel();
    // Right half: the floor y = 0 (1 below the eye) where a ray goes down, else background.
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * W + size_t(x);
            if (x < W / 2) {
                depth[i] = 5.f;
                continue;
            }
            // Planar depth of the floor on this pixel's ray: the camera-space ray (u, v, -1)
            // meets y_cam = -1 at depth 1 / -v.
            const double v = -((y + 0.5) - H / 2.0) / (H / 2.0) / (1.0 / std::tan(kPi / 6.0));
            depth[i] = v < -1e-3 ? float(1.0 / -v) : 1e10f;
        }
    exr::unprojectRows(c2p, c2w, depth.data(), false, {p[0].data(), p[1].data(), p[2].data()}, W, 0,
                       H);
    const double eye[3] = {0, 1, 0};
    exr::normalsFromPositionsRows({p[0].data(), p[1].data(), p[2].data()}, depth.data(), eye,
                                  {n[0].data(), n[1].data(), n[2].data()}, W, H, 0, H);
    int wall = 0, floor = 0, background = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * W + size_t(x);
            const float nx = n[0][i], ny = n[1][i], nz = n[2][i];
            if (depth[i] >= 1e9f) {
                EXPECT_EQ(nx * nx + ny * ny + nz * nz, 0.f) << x << "," << y;
                ++background;
            } else if (x < W / 2) {  // the wall faces the camera: +z (the camera looks down -z)
                EXPECT_NEAR(nz, 1.f, 1e-4) << x << "," << y;
                ++wall;
            } else {  // the floor faces up
                EXPECT_NEAR(ny, 1.f, 1e-3) << x << "," << y;
                ++floor;
            }
        }
    EXPECT_EQ(wall, W / 2 * H);
    EXPECT_GT(floor, W / 2 * H / 3);
    EXPECT_GT(background, 0);
}
