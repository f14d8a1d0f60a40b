#pragma once
// Per-execute scratch planes shared by every A-Trous instance of the process. Five instances
// each owning 12 full-resolution planes would hold ~500 MB at 1080p; the planes are only needed
// while one instance executes, so instances take turns on one set (a mutex serialises them if an
// executor ever runs passes concurrently). Not temporal state: contents die with the execute.
#include <kestrel/Image.h>

#include <mutex>
#include <vector>

class ScratchArena {
public:
    /// Locks the arena and returns `count` planes of at least `pixels` floats each.
    class Lease {
    public:
        Lease(std::unique_lock<std::mutex> lock, std::vector<float*> planes)
            : lock_(std::move(lock)), planes_(std::move(planes)) {}
        float* operator[](size_t i) const { return planes_[i]; }

    private:
        std::unique_lock<std::mutex> lock_;
        std::vector<float*> planes_;
    };
    static Lease acquire(size_t count, size_t pixels);
};
