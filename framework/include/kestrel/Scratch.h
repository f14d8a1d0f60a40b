#pragma once
// Scratch planes for a pass's working data within one execute: a process-wide pool of plane
// sets. A lease takes a free set (growing it to the size asked for) and gives it back when it
// ends, so concurrent leases (one per band a thread filters) never share a set, and sets are
// reused across bands, passes and frames instead of being reallocated. Not temporal state:
// contents are undefined when a lease starts and die when it ends (temporal state goes through
// history edges).
//
//   auto lease = kestrel::ScratchPool::acquire(12, bandRows * width);
//   float* work = lease[0];
#include <cstddef>
#include <vector>

namespace kestrel {

class ScratchPool {
public:
    /// A set of planes of at least the asked size, owned until the lease ends.
    class Lease {
    public:
        Lease(size_t set, std::vector<float*> planes);
        Lease(const Lease&) = delete;
        Lease& operator=(const Lease&) = delete;
        ~Lease();
        float* operator[](size_t i) const { return planes_[i]; }

    private:
        size_t set_;
        std::vector<float*> planes_;
    };
    /// `count` 64-byte-aligned planes of at least `pixels` 32-bit values each.
    static Lease acquire(size_t count, size_t pixels);
    /// Bytes held by the pool (all sets, leased or free).
    static size_t bytes();
};

}  // namespace kestrel
