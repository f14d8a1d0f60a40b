#pragma once
// Minimal float vector / matrix helpers for the path tracer (internal).
#include <cmath>

#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

struct V3 {
    float x = 0, y = 0, z = 0;
};
inline V3 operator+(V3 a, V3 b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline V3 operator-(V3 a, V3 b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline V3 operator-(V3 a) {
    return {-a.x, -a.y, -a.z};
}
inline V3 operator*(V3 a, float s) {
    return {a.x * s, a.y * s, a.z * s};
}
inline V3 operator*(float s, V3 a) {
    return {a.x * s, a.y * s, a.z * s};
}
inline V3 operator*(V3 a, V3 b) {
    return {a.x * b.x, a.y * b.y, a.z * b.z};
}
inline V3& operator+=(V3& a, V3 b) {
    return a = a + b;
}
inline float dot(V3 a, V3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline V3 cross(V3 a, V3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(V3 a) {
    return std::sqrt(dot(a, a));
}
inline V3 normalize(V3 a) {
    const float l = length(a);
    return l > 0.f ? a * (1.f / l) : V3{0, 0, 1};
}
inline float comp(V3 a, int i) {
    return i == 0 ? a.x : (i == 1 ? a.y : a.z);
}

/// p' = M (p, 1): returns xyz (no divide) and w.
inline V3 xformPoint(const Mat4& m, V3 p, float* w = nullptr) {
    const Vec4 q = m.transformPoint({p.x, p.y, p.z});
    if (w) *w = q.w;
    return {q.x, q.y, q.z};
}
/// The 3x3 part of M times d (Mat4 * (d, 0) would add the translation's 0 products).
inline V3 xformDir(const Mat4& m, V3 d) {
    const auto& a = m.m;
    return {a[0][0] * d.x + a[0][1] * d.y + a[0][2] * d.z,
            a[1][0] * d.x + a[1][1] * d.y + a[1][2] * d.z,
            a[2][0] * d.x + a[2][1] * d.y + a[2][2] * d.z};
}
/// Rigid transform: rotation by `angle` (radians) about +Y, then translation.
inline Mat4 rigidY(float angle, V3 t) {
    const float c = std::cos(angle), s = std::sin(angle);
    return {c, 0, s, t.x, 0, 1, 0, t.y, -s, 0, c, t.z, 0, 0, 0, 1};
}
/// Inverse of a rigid transform (orthonormal rotation + translation): exact transpose, where
/// kestrel::inverse would eliminate in double and round.
inline Mat4 rigidInverse(const Mat4& m) {
    Mat4 r{};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r.m[i][j] = m.m[j][i];
    for (int i = 0; i < 3; ++i)
        r.m[i][3] = -(r.m[i][0] * m.m[0][3] + r.m[i][1] * m.m[1][3] + r.m[i][2] * m.m[2][3]);
    r.m[3][3] = 1;
    return r;
}

// Orthonormal basis around n (Duff et al., "Building an Orthonormal Basis, Revisited", JCGT 2017).
inline void basis(V3 n, V3& t, V3& b) {
    const float sign = std::copysign(1.f, n.z);
    const float a = -1.f / (sign + n.z);
    const float c = n.x * n.y * a;
    t = {1.f + sign * n.x * n.x * a, sign * c, -sign * n.x};
    b = {c, sign + n.y * n.y * a, -n.y};
}

}  // namespace kestrel::scenegen
