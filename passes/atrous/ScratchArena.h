#pragma once
// Scratch planes shared by every A-Trous instance of the process: a pool of plane sets, one per
// band being filtered at a time (so at most one per thread), reused across bands, instances and
// frames. Five instances each owning full-resolution scratch would hold ~500 MB at 1080p; bands
// only need a few dozen rows. Not temporal state: contents die with the band.
#include <kestrel/Image.h>

#include <cstddef>
#include <vector>

class ScratchArena {
public:
    /// A set of `count` planes of at least `pixels` floats each, owned until the lease ends.
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
    static Lease acquire(size_t count, size_t pixels);
    /// Bytes held by the pool (for tests and memory reports).
    static size_t bytes();
};
