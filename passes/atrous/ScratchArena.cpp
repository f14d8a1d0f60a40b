#include "ScratchArena.h"

#include <mutex>

namespace {
struct PlaneSet {
    std::vector<kestrel::PlaneStorage> planes;
    size_t pixels = 0;
    bool inUse = false;
};
struct Arena {
    std::mutex mutex;
    std::vector<PlaneSet> sets;
};
Arena& arena() {
    static Arena a;
    return a;
}
}  // namespace

ScratchArena::Lease::Lease(size_t set, std::vector<float*> planes)
    : set_(set), planes_(std::move(planes)) {}

ScratchArena::Lease::~Lease() {
    Arena& a = arena();
    std::lock_guard lock(a.mutex);
    a.sets[set_].inUse = false;
}

ScratchArena::Lease ScratchArena::acquire(size_t count, size_t pixels) {
    Arena& a = arena();
    std::lock_guard lock(a.mutex);
    size_t k = 0;
    while (k < a.sets.size() && a.sets[k].inUse) ++k;
    if (k == a.sets.size()) a.sets.emplace_back();
    PlaneSet& set = a.sets[k];
    set.inUse = true;
    if (pixels > set.pixels) {  // grow: planes of the new size (contents are scratch)
        set.planes.clear();
        set.pixels = pixels;
    }
    while (set.planes.size() < count) set.planes.push_back(kestrel::allocatePlane(set.pixels));
    std::vector<float*> ptrs;
    for (size_t i = 0; i < count; ++i) ptrs.push_back(set.planes[i].get());
    return Lease(k, std::move(ptrs));
}

size_t ScratchArena::bytes() {
    Arena& a = arena();
    std::lock_guard lock(a.mutex);
    size_t total = 0;
    for (const auto& s : a.sets) total += s.planes.size() * s.pixels * sizeof(float);
    return total;
}
