#pragma once
// Scratch planes for a pass's working data within one execute. ScratchArena (below) cuts them
// from the pass's idle planes first; ScratchPool is the process-wide pool of plane sets behind
// it. A lease takes a free set (growing it to the size asked for) and gives it back when it
// ends, so concurrent leases (one per band a thread filters) never share a set, and sets are
// reused across bands, passes and frames instead of being reallocated. Not temporal state:
// contents are undefined when a lease starts and die when it ends (temporal state goes through
// history edges).
//
//   auto lease = kestrel::ScratchPool::acquire(12, bandRows * width);
//   float* work = lease[0];
#include <cstddef>
#include <mutex>
#include <span>
#include <vector>

namespace kestrel {

class ScratchArena;

class ScratchPool {
public:
    /// A set of planes of at least the asked size, owned until the lease ends.
    class Lease {
    public:
        Lease(size_t set, std::vector<float*> planes);
        /// Pieces of a ScratchArena's idle planes.
        Lease(ScratchArena& arena, std::vector<size_t> pieces, std::vector<float*> planes);
        Lease(const Lease&) = delete;
        Lease& operator=(const Lease&) = delete;
        ~Lease();
        float* operator[](size_t i) const { return planes_[i]; }

    private:
        size_t set_ = 0;
        ScratchArena* arena_ = nullptr;
        std::vector<size_t> pieces_;
        std::vector<float*> planes_;
    };
    /// `count` 64-byte-aligned planes of at least `pixels` 32-bit values each.
    static Lease acquire(size_t count, size_t pixels);
    /// Bytes held by the pool (all sets, leased or free).
    static size_t bytes();
};

/// Scratch cut from a pass's idle planes (PassIO::idlePlanes: memory the plan holds anyway and
/// no resource occupies while the pass runs), so that the pool grows only where a step has too
/// few. The planes are cut into pieces of the first lease's size; a lease that finds too few
/// free pieces, or asks more per plane, comes from the pool. One per execute, shared by its
/// threads; it must outlive its leases.
///
///   ScratchArena arena(io.idlePlanes(), ctx.extent.pixels());
///   auto lease = arena.acquire(4, bandRows * width);  // on any thread of the execute
class ScratchArena {
public:
    ScratchArena(std::span<float* const> idlePlanes, size_t planePixels);
    ~ScratchArena();
    ScratchArena(const ScratchArena&) = delete;
    ScratchArena& operator=(const ScratchArena&) = delete;
    /// As ScratchPool::acquire.
    ScratchPool::Lease acquire(size_t count, size_t pixels);
    /// Leases given from the idle planes so far (for tests).
    size_t lentCount() const;

private:
    friend class ScratchPool::Lease;
    void release(const std::vector<size_t>& pieces);

    mutable std::mutex mutex_;
    std::vector<float*> planes_;
    size_t planePixels_;
    size_t pieceFloats_ = 0;  // fixed by the first lease
    std::vector<float*> pieces_;
    std::vector<bool> taken_;
    size_t lent_ = 0;
};

}  // namespace kestrel
