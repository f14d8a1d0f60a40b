#include "kestrel/Math.h"

#include <cmath>

namespace kestrel {

std::optional<Mat4> inverse(const Mat4& a) {
    // Gauss-Jordan elimination with partial pivoting, in double precision.
    double m[4][8];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 8; ++j) m[i][j] = j < 4 ? a.m[i][j] : (j - 4 == i ? 1.0 : 0.0);
    for (int col = 0; col < 4; ++col) {
        int pivot = col;
        for (int r = col + 1; r < 4; ++r)
            if (std::fabs(m[r][col]) > std::fabs(m[pivot][col])) pivot = r;
        if (std::fabs(m[pivot][col]) < 1e-12) return std::nullopt;
        if (pivot != col)
            for (int j = 0; j < 8; ++j) std::swap(m[col][j], m[pivot][j]);
        double inv = 1.0 / m[col][col];
        for (int j = 0; j < 8; ++j) m[col][j] *= inv;
        for (int r = 0; r < 4; ++r) {
            if (r == col) continue;
            double f = m[r][col];
            for (int j = 0; j < 8; ++j) m[r][j] -= f * m[col][j];
        }
    }
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) r.m[i][j] = float(m[i][j + 4]);
    return r;
}

bool pointOnPixelRay(const Mat4& cameraToPixel, double px, double py, double zc, double& x,
                     double& y) {
    const auto& A = cameraToPixel.m;
    double a[4], b[4];
    for (int k = 0; k < 4; ++k) {
        a[k] = A[0][k] - px * A[3][k];
        b[k] = A[1][k] - py * A[3][k];
    }
    const double det = a[0] * b[1] - a[1] * b[0];
    if (!(std::fabs(det) > 1e-12)) return false;
    const double ra = -(a[2] * zc + a[3]), rb = -(b[2] * zc + b[3]);
    x = (ra * b[1] - a[1] * rb) / det;
    y = (a[0] * rb - ra * b[0]) / det;
    return std::isfinite(x) && std::isfinite(y);
}

}  // namespace kestrel
