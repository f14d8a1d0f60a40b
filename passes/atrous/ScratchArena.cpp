#include "ScratchArena.h"

namespace {
struct Arena {
    std::mutex mutex;
    std::vector<kestrel::PlaneStorage> planes;
    size_t pixels = 0;
};
Arena& arena() {
    static Arena a;
    return a;
}
}  // namespace

ScratchArena::Lease ScratchArena::acquire(size_t count, size_t pixels) {
    Arena& a = arena();
    std::unique_lock lock(a.mutex);
    if (pixels > a.pixels) {
        a.planes.clear();
        a.pixels = pixels;
    }
    while (a.planes.size() < count) a.planes.push_back(kestrel::allocatePlane(a.pixels));
    std::vector<float*> ptrs;
    for (size_t i = 0; i < count; ++i) ptrs.push_back(a.planes[i].get());
    return Lease(std::move(lock), std::move(ptrs));
}
