#include "Unproject.h"

#include <cmath>

namespace kestrel::exr {

namespace {

bool isBackground(double d) {
    return !(d > 0.0) || d >= 1e9;
}

}  // namespace

void unprojectRows(const Mat4& cameraToPixel, const Mat4& cameraToWorld, const float* depth,
                   bool rayLength, std::array<float*, 3> out, int W, int y0, int y1) {
    const auto& M = cameraToWorld.m;
    float *ox = out[0], *oy = out[1], *oz = out[2];
    for (int y = y0; y < y1; ++y) {
        const double py = y + 0.5;
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * size_t(W) + size_t(x);
            const double px = x + 0.5, d = depth[i];
            ox[i] = oy[i] = oz[i] = 0.f;
            if (isBackground(d)) continue;
            // Planar depth: the ray's point at z = -d. A ray length (a perspective camera, rays
            // from the eye): the planar-depth-1 point scaled to that length.
            double xc, yc, zc = rayLength ? -1.0 : -d;
            if (!pointOnPixelRay(cameraToPixel, px, py, zc, xc, yc)) continue;
            if (rayLength) {
                const double s = d / std::sqrt(xc * xc + yc * yc + 1.0);
                xc *= s, yc *= s, zc = -s;
            }
            const double c[4] = {xc, yc, zc, 1.0};
            double w[3] = {0, 0, 0};
            for (int r = 0; r < 3; ++r)
                for (int k = 0; k < 4; ++k) w[r] += double(M[r][k]) * c[k];
            if (!(std::isfinite(w[0]) && std::isfinite(w[1]) && std::isfinite(w[2]))) continue;
            ox[i] = float(w[0]);
            oy[i] = float(w[1]);
            oz[i] = float(w[2]);
        }
    }
}

void normalsFromPositionsRows(const std::array<const float*, 3>& position, const float* depth,
                              const double eye[3], std::array<float*, 3> out, int W, int H, int y0,
                              int y1) {
    auto at = [&](size_t i, double p[3]) {
        for (int c = 0; c < 3; ++c) p[c] = position[size_t(c)][i];
    };
    // The neighbour (-1 or +1 along stride, within [0, n)) on a surface whose depth is closer
    // to d; 0 where neither is on a surface.
    auto closer = [&](size_t i, int k, int n, size_t stride, double d) {
        const bool lo = k > 0 && !isBackground(depth[i - stride]),
                   hi = k + 1 < n && !isBackground(depth[i + stride]);
        if (lo && hi)
            return std::fabs(double(depth[i - stride]) - d) <=
                           std::fabs(double(depth[i + stride]) - d)
                       ? -1
                       : 1;
        return lo ? -1 : hi ? 1 : 0;
    };
    for (int y = y0; y < y1; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * size_t(W) + size_t(x);
            for (int c = 0; c < 3; ++c) out[size_t(c)][i] = 0.f;
            const double d = depth[i];
            if (isBackground(d)) continue;
            double p[3], toEye[3];
            at(i, p);
            for (int c = 0; c < 3; ++c) toEye[c] = eye[c] - p[c];
            double n[3] = {toEye[0], toEye[1], toEye[2]};
            const int sx = closer(i, x, W, 1, d), sy = closer(i, y, H, size_t(W), d);
            if (sx && sy) {
                double px[3], py[3], tx[3], ty[3];
                at(sx > 0 ? i + 1 : i - 1, px);
                at(sy > 0 ? i + size_t(W) : i - size_t(W), py);
                for (int c = 0; c < 3; ++c) {
                    tx[c] = (px[c] - p[c]) * sx;
                    ty[c] = (py[c] - p[c]) * sy;
                }
                const double cr[3] = {tx[1] * ty[2] - tx[2] * ty[1], tx[2] * ty[0] - tx[0] * ty[2],
                                      tx[0] * ty[1] - tx[1] * ty[0]};
                const double facing = cr[0] * toEye[0] + cr[1] * toEye[1] + cr[2] * toEye[2];
                if (std::isfinite(facing) && facing != 0.0)
                    for (int c = 0; c < 3; ++c) n[c] = facing > 0 ? cr[c] : -cr[c];
            }
            const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (!(len > 0.0) || !std::isfinite(len)) continue;
            for (int c = 0; c < 3; ++c) out[size_t(c)][i] = float(n[c] / len);
        }
}

void skyMotionRows(const Mat4& cameraToPixel, const Mat4& cameraToWorld,
                   const Mat4& prevWorldToPixel, const float* depth, std::array<float*, 2> motion,
                   int W, int y0, int y1) {
    const auto& M = cameraToWorld.m;
    const auto& P = prevWorldToPixel.m;
    for (int y = y0; y < y1; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * size_t(W) + size_t(x);
            if (!isBackground(depth[i])) continue;
            const double px = x + 0.5, py = y + 0.5;
            double xc, yc;
            if (!pointOnPixelRay(cameraToPixel, px, py, -1.0, xc, yc)) continue;
            const double c[3] = {xc, yc, -1.0};
            double dir[3] = {0, 0, 0};  // the ray's world direction: rotation only
            for (int r = 0; r < 3; ++r)
                for (int k = 0; k < 3; ++k) dir[r] += double(M[r][k]) * c[k];
            double q[4] = {0, 0, 0, 0};  // the previous frame's pixel of (dir, 0)
            for (int r = 0; r < 4; ++r)
                for (int k = 0; k < 3; ++k) q[r] += double(P[r][k]) * dir[k];
            if (!(q[3] > 1e-12)) continue;  // behind the previous camera
            const double mx = q[0] / q[3] - px, my = q[1] / q[3] - py;
            if (!(std::isfinite(mx) && std::isfinite(my))) continue;
            motion[0][i] = float(mx);
            motion[1][i] = float(my);
        }
}

}  // namespace kestrel::exr
