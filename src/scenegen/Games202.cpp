#include "Games202.h"

#include <bit>
#include <cstring>

#include "VecMath.h"

namespace kestrel::scenegen {

Mat4 games202WorldToCamera(const FrameAovs& f) {
    Mat4 v = f.worldToCamera;
    for (int c = 0; c < 4; ++c) v.m[2][size_t(c)] = -v.m[2][size_t(c)];
    return v;
}

Mat4 games202WorldToScreen(const FrameAovs& f) {
    const float w = float(f.width), h = float(f.height);
    const float fx = 0.5f * w * f.projection.m[0][0], fy = 0.5f * h * f.projection.m[1][1];
    constexpr float kNear = 0.01f;
    // Pinhole intrinsics with y down, acting on (x_cam, y_cam, z_cam forward, 1).
    const Mat4 k = {fx, 0, 0.5f * w, 0, 0, -fy, 0.5f * h, 0, 0, 0, 1, -kNear, 0, 0, 1, 0};
    return k * games202WorldToCamera(f);
}

std::vector<char> games202MatrixFile(const FrameAovs& f) {
    static_assert(std::endian::native == std::endian::little, "the .mat format is little-endian");
    static_assert(sizeof(Mat4) == 64, "a .mat matrix is 16 floats, row-major");
    const int32_t n = int32_t(f.objectToWorld.size());
    std::vector<char> bytes(4 + size_t(n + 2) * 64);
    std::memcpy(bytes.data(), &n, 4);
    size_t off = 4;
    auto put = [&](const Mat4& m) {
        std::memcpy(bytes.data() + off, m.m.data(), 64);
        off += 64;
    };
    // objectToWorld holds ids 0..N-1 (the scene's ids are already dense).
    for (const auto& [id, m] : f.objectToWorld) put(m);
    put(games202WorldToCamera(f));
    put(games202WorldToScreen(f));
    return bytes;
}

}  // namespace kestrel::scenegen
