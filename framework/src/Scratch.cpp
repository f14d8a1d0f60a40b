#include "kestrel/Scratch.h"

#include <algorithm>
#include <cassert>
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

ScratchPool::Lease::Lease(ScratchArena& arena, std::vector<size_t> pieces,
                          std::vector<float*> planes)
    : arena_(&arena), pieces_(std::move(pieces)), planes_(std::move(planes)) {}

ScratchPool::Lease::~Lease() {
    if (arena_) {
        arena_->release(pieces_);
        return;
    }
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

ScratchArena::ScratchArena(std::span<float* const> idlePlanes, size_t planePixels)
    : planes_(idlePlanes.begin(), idlePlanes.end()), planePixels_(planePixels) {}

ScratchPool::Lease ScratchArena::acquire(size_t count, size_t pixels) {
    {
        std::lock_guard lock(mutex_);
        if (pieceFloats_ == 0 && !planes_.empty()) {
            // Pieces start 64 bytes apart, as the planes do (allocatePlane).
            pieceFloats_ = (std::max<size_t>(pixels, 1) + 15) / 16 * 16;
            for (float* plane : planes_)
                for (size_t at = 0; at + pieceFloats_ <= planePixels_; at += pieceFloats_)
                    pieces_.push_back(plane + at);
            taken_.assign(pieces_.size(), false);
        }
        if (pixels <= pieceFloats_) {
            std::vector<size_t> found;
            for (size_t i = 0; i < pieces_.size() && found.size() < count; ++i)
                if (!taken_[i]) found.push_back(i);
            if (found.size() == count) {
                std::vector<float*> ptrs;  // all allocation before any piece is marked taken
                for (size_t i : found) ptrs.push_back(pieces_[i]);
                for (size_t i : found) taken_[i] = true;
                ++lent_;
                return ScratchPool::Lease(*this, std::move(found), std::move(ptrs));
            }
        }
    }
    return ScratchPool::acquire(count, pixels);
}

ScratchArena::~ScratchArena() {
    // Every lease ends first: a lease's destructor gives its pieces back to this arena.
    assert(std::none_of(taken_.begin(), taken_.end(), [](bool t) { return t; }));
}

size_t ScratchArena::lentCount() const {
    std::lock_guard lock(mutex_);
    return lent_;
}

void ScratchArena::release(const std::vector<size_t>& pieces) {
    std::lock_guard lock(mutex_);
    for (size_t i : pieces) taken_[i] = false;
}

}  // namespace kestrel
