#include "kestrel/Scratch.h"

#include <mutex>

#include "kestrel/Image.h"

namespace kestrel {

namespace {
struct PlaneSet {
    std::vector<PlaneStorage> planes;
    size_t pixels = 0;
    bool inUse = false;
};
struct Pool {
    std::mutex mutex;
    std::vector<PlaneSet> sets;
};
Pool& pool() {
    static Pool p;
    return p;
}
}  // namespace

ScratchPool::Lease::Lease(size_t set, std::vector<float*> planes)
    : set_(set), planes_(std::move(planes)) {}

ScratchPool::Lease::~Lease() {
    Pool& p = pool();
    std::lock_guard lock(p.mutex);
    p.sets[set_].inUse = false;
}

ScratchPool::Lease ScratchPool::acquire(size_t count, size_t pixels) {
    Pool& p = pool();
    std::lock_guard lock(p.mutex);
    size_t k = 0;
    while (k < p.sets.size() && p.sets[k].inUse) ++k;
    if (k == p.sets.size()) p.sets.emplace_back();
    PlaneSet& set = p.sets[k];
    set.inUse = true;
    if (pixels > set.pixels) {  // grow: planes of the new size (contents are scratch)
        set.planes.clear();
        set.pixels = pixels;
    }
    while (set.planes.size() < count) set.planes.push_back(allocatePlane(set.pixels));
    std::vector<float*> ptrs;
    for (size_t i = 0; i < count; ++i) ptrs.push_back(set.planes[i].get());
    return Lease(k, std::move(ptrs));
}

size_t ScratchPool::bytes() {
    Pool& p = pool();
    std::lock_guard lock(p.mutex);
    size_t total = 0;
    for (const auto& s : p.sets) total += s.planes.size() * s.pixels * sizeof(float);
    return total;
}

}  // namespace kestrel
