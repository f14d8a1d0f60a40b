#include "kestrel/Scratch.h"

#include <algorithm>
#include <mutex>

#include "kestrel/Image.h"

namespace kestrel {

namespace {
/// Each plane of a set has its own size: passes lease different counts of different sizes
/// (A-Trous 4 planes of a band and its halo, variance estimation 10 smaller ones), and a set
/// sized by the largest count times the largest size would hold memory nobody leases (8 MB at
/// 1080p with two threads).
struct PlaneSet {
    struct Plane {
        PlaneStorage storage;
        size_t pixels = 0;  // what storage holds (0: nothing)
    };
    std::vector<Plane> planes;
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
    if (set.planes.size() < count) set.planes.resize(count);
    std::vector<float*> ptrs;
    for (size_t i = 0; i < count; ++i) {
        PlaneSet::Plane& plane = set.planes[i];
        if (!plane.storage || plane.pixels < pixels) {  // grow this plane (contents are scratch)
            plane.storage.reset();
            plane.pixels = 0;
            plane.storage = allocatePlane(std::max<size_t>(pixels, 1));
            plane.pixels = std::max<size_t>(pixels, 1);
        }
        ptrs.push_back(plane.storage.get());
    }
    set.inUse = true;  // after the allocations: one that throws leaves the set free and whole
    return Lease(k, std::move(ptrs));
}

size_t ScratchPool::bytes() {
    Pool& p = pool();
    std::lock_guard lock(p.mutex);
    size_t total = 0;
    for (const auto& s : p.sets)
        for (const auto& plane : s.planes) total += plane.pixels * sizeof(float);
    return total;
}

}  // namespace kestrel
