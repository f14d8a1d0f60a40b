#include "kestrel/Image.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <new>

#if __has_include(<sys/mman.h>)
#include <sys/mman.h>
#endif

namespace kestrel {

void AlignedFree::operator()(float* p) const {
    if (p) std::free(reinterpret_cast<char*>(p) - shift);
}

PlaneStorage allocatePlane(size_t count) {
    // Round up to whole cache lines so every plane starts 64-byte aligned and SIMD loops may
    // read a full vector past the last pixel of a row without leaving the allocation.
    const size_t bytes = ((std::max<size_t>(count, 1) * sizeof(float) + 63) / 64) * 64;
    // Large planes come page-aligned from mmap, so pixel (x, y) of every plane would share one
    // L1 set (address bits 6-11): a kernel streaming a dozen planes at once (A-Trous reads 10
    // per tap) then evicts its own lines, 8 ways being fewer than the planes. Successive planes
    // start 7 cache lines further into a page (7 is coprime to the 64 sets), so up to 64
    // planes read together fall into different sets.
    static std::atomic<unsigned> counter{0};
    const size_t shift = size_t((counter.fetch_add(1, std::memory_order_relaxed) * 7u) % 64u) * 64u;
    // Planes of several megabytes in transparent huge pages where the kernel offers them
    // (madvise mode): a 1080p graph's planes are otherwise ~90,000 pages of 4 KB, whose first-touch
    // faults took 45% of a one-frame run's samples in a VM (perf).
    constexpr size_t kHuge = size_t(2) << 20;
    const bool huge = bytes >= 2 * kHuge;
    const size_t total = huge ? (bytes + shift + kHuge - 1) / kHuge * kHuge : bytes + shift;
    void* p = std::aligned_alloc(huge ? kHuge : 64, total);
    if (!p) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
    if (huge) madvise(p, total, MADV_HUGEPAGE);  // advice only: failure changes nothing
#endif
    float* plane = reinterpret_cast<float*>(static_cast<char*>(p) + shift);
    std::fill_n(plane, bytes / sizeof(float), 0.f);
    return PlaneStorage(plane, AlignedFree{shift});
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
