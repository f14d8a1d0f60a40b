#include "kestrel/Image.h"

#include <algorithm>
#include <cstdlib>
#include <new>

namespace kestrel {

void AlignedFree::operator()(float* p) const { std::free(p); }

PlaneStorage allocatePlane(size_t count) {
    // Round up to whole cache lines so every plane starts 64-byte aligned and SIMD loops may
    // read a full vector past the last pixel of a row without leaving the allocation.
    size_t bytes = ((std::max<size_t>(count, 1) * sizeof(float) + 63) / 64) * 64;
    void* p = std::aligned_alloc(64, bytes);
    if (!p) throw std::bad_alloc();
    std::fill_n(static_cast<float*>(p), bytes / sizeof(float), 0.f);
    return PlaneStorage(static_cast<float*>(p));
}

Image::Image(Extent extent, Format format) {
    view_.extent = extent;
    view_.format = format;
    for (int c = 0; c < channelCount(format); ++c) {
        storage_[size_t(c)] = allocatePlane(extent.pixels());
        view_.planes[size_t(c)] = storage_[size_t(c)].get();
    }
}

void Image::fill(float value) {
    for (int c = 0; c < view_.channels(); ++c)
        std::fill_n(view_.planes[size_t(c)], view_.pixels(), value);
}

}  // namespace kestrel
