#pragma once
// Memory lent to the EXR decoder and encoder for their chunk buffers: the transient planes the
// graph's memory plan leaves idle while the loader or writer runs (PassIO::idlePlanes).
#include <cstddef>
#include <span>

namespace kestrel::exr {

/// `regions` of `bytes` each, writable for the duration of one call.
struct Workspace {
    std::span<float* const> regions;
    size_t bytes = 0;
};

}  // namespace kestrel::exr
