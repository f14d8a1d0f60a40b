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

inline Mat4 identity4() {
    return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
}
inline Mat4 mul(const Mat4& a, const Mat4& b) {
    Mat4 r{};
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            float s = 0;
            for (int k = 0; k < 4; ++k) s += a[i * 4 + k] * b[k * 4 + j];
            r[i * 4 + j] = s;
        }
    return r;
}
/// p' = M (p, 1): returns xyz (no divide) and w.
inline V3 xformPoint(const Mat4& m, V3 p, float* w = nullptr) {
    if (w) *w = m[12] * p.x + m[13] * p.y + m[14] * p.z + m[15];
    return {m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3],
            m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
            m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
}
inline V3 xformDir(const Mat4& m, V3 d) {
    return {m[0] * d.x + m[1] * d.y + m[2] * d.z, m[4] * d.x + m[5] * d.y + m[6] * d.z,
            m[8] * d.x + m[9] * d.y + m[10] * d.z};
}
/// Rigid transform: rotation by `angle` (radians) about +Y, then translation.
inline Mat4 rigidY(float angle, V3 t) {
    const float c = std::cos(angle), s = std::sin(angle);
    return {c, 0, s, t.x, 0, 1, 0, t.y, -s, 0, c, t.z, 0, 0, 0, 1};
}
/// Inverse of a rigid transform (orthonormal rotation + translation).
inline Mat4 rigidInverse(const Mat4& m) {
    Mat4 r{};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r[i * 4 + j] = m[j * 4 + i];
    for (int i = 0; i < 3; ++i)
        r[i * 4 + 3] = -(r[i * 4 + 0] * m[3] + r[i * 4 + 1] * m[7] + r[i * 4 + 2] * m[11]);
    r[15] = 1;
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
