#pragma once
// Helpers shared by the room and street renderers: row threading and planar image writes.
#include <algorithm>
#include <array>
#include <atomic>
#include <thread>
#include <vector>

#include "VecMath.h"
#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

constexpr float kBackgroundDepth = 1e10f;  // kestrel::kBackgroundDepth (Conventions.h)
constexpr int32_t kBackgroundId = -1;

/// Runs fn(row) for every row on `threads` std::threads (rows handed out by an atomic counter;
/// every row's result depends only on the row, so the split does not matter).
template <class Fn>
void forEachRow(int height, int threads, Fn&& fn) {
    int n = threads > 0 ? threads : int(std::max(1u, std::thread::hardware_concurrency()));
    n = std::min(n, height);
    std::atomic<int> next{0};
    auto worker = [&] {
        for (int y = next++; y < height; y = next++) fn(y);
    };
    if (n <= 1) {
        worker();
        return;
    }
    std::vector<std::thread> pool;
    pool.reserve(size_t(n - 1));
    for (int t = 0; t < n - 1; ++t) pool.emplace_back(worker);
    worker();
    for (auto& th : pool) th.join();
}

inline void set3(std::array<std::vector<float>, 3>& img, size_t k, V3 v) {
    img[0][k] = v.x;
    img[1][k] = v.y;
    img[2][k] = v.z;
}

template <size_t N>
void alloc(std::array<std::vector<float>, N>& img, size_t n) {
    for (auto& c : img) c.assign(n, 0.f);
}

/// Every AOV plane of a frame, at the background's values.
inline void allocFrame(FrameAovs& f, size_t n) {
    alloc(f.color, n), alloc(f.albedo, n), alloc(f.emission, n), alloc(f.direct, n);
    alloc(f.indirect, n), alloc(f.normal, n), alloc(f.position, n), alloc(f.motion, n);
    alloc(f.diffuse, n), alloc(f.diffuseAlbedo, n), alloc(f.specular, n),
        alloc(f.specularAlbedo, n);
    f.depth.assign(n, kBackgroundDepth);
    f.objectId.assign(n, kBackgroundId);
}

}  // namespace kestrel::scenegen
