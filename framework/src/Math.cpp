#include "kestrel/Math.h"

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

}  // namespace kestrel
