#pragma once
// Small fixed-size vector and matrix types for per-frame (not per-pixel hot path) scene data.
// Matrices are row-major m[row][col] with the column-vector convention p' = M * (x, y, z, 1)^T.
#include <array>
#include <cmath>
#include <optional>

namespace kestrel {

struct Vec3 {
    float x = 0, y = 0, z = 0;
};
struct Vec4 {
    float x = 0, y = 0, z = 0, w = 0;
};

struct Mat4 {
    std::array<std::array<float, 4>, 4> m{};  // m[row][col]

    static Mat4 identity() {
        Mat4 r;
        for (int i = 0; i < 4; ++i) r.m[i][i] = 1.f;
        return r;
    }
    Vec4 operator*(const Vec4& v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z + m[0][3] * v.w,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z + m[1][3] * v.w,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z + m[2][3] * v.w,
                m[3][0] * v.x + m[3][1] * v.y + m[3][2] * v.z + m[3][3] * v.w};
    }
    Mat4 operator*(const Mat4& o) const {
        Mat4 r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) {
                float s = 0;
                for (int k = 0; k < 4; ++k) s += m[i][k] * o.m[k][j];
                r.m[i][j] = s;
            }
        return r;
    }
    Vec4 transformPoint(const Vec3& p) const { return (*this) * Vec4{p.x, p.y, p.z, 1.f}; }
    bool operator==(const Mat4&) const = default;
};

/// Inverse by cofactors in double precision; nullopt when singular.
std::optional<Mat4> inverse(const Mat4& a);

/// The camera-space (x, y) where pixel position (px, py)'s ray meets the plane z = zc (camera
/// space; the camera looks down -Z): solves (row0 - px row3) . c = 0 and (row1 - py row3) . c = 0
/// for c = (x, y, zc, 1), in double precision. False where the camera cannot invert it.
bool pointOnPixelRay(const Mat4& cameraToPixel, double px, double py, double zc, double& x,
                     double& y);

}  // namespace kestrel
