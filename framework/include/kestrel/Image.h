#pragma once
// Planar images. Every channel is its own contiguous, 64-byte-aligned plane of width*height
// 32-bit values (float, or int32 for Format::Int32), rows top to bottom. Planar buffers keep
// kernels SIMD-friendly and let the resource pool alias memory plane by plane.
#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <memory>

#include "kestrel/Format.h"

namespace kestrel {

/// A non-owning view of a planar image. Cheap to copy.
struct ImageView {
    Extent extent{};
    Format format = Format::Float;
    std::array<float*, 4> planes{};  ///< channel planes; unused entries are null

    int width() const { return extent.width; }
    int height() const { return extent.height; }
    int channels() const { return channelCount(format); }
    size_t pixels() const { return extent.pixels(); }
    bool valid() const { return planes[0] != nullptr; }

    float* channel(int c) const { return planes[size_t(c)]; }
    float* row(int c, int y) const { return planes[size_t(c)] + size_t(y) * size_t(extent.width); }
    float& at(int c, int x, int y) const { return row(c, y)[x]; }
    /// The single plane of an Int32 image.
    int32_t* ints() const { return reinterpret_cast<int32_t*>(planes[0]); }
    int32_t& atInt(int x, int y) const {
        return ints()[size_t(y) * size_t(extent.width) + size_t(x)];
    }
};

/// 64-byte-aligned storage for `count` 32-bit values. Planes are staggered within a page (see
/// allocatePlane) so that the deleter needs the plane's offset from its allocation.
struct AlignedFree {
    size_t shift = 0;
    void operator()(float* p) const;
};
using PlaneStorage = std::unique_ptr<float[], AlignedFree>;
PlaneStorage allocatePlane(size_t count);

/// An owning planar image: for tests, tools and a pass's private scratch (graph resources come
/// from the engine's pool instead). Zero-initialised.
class Image {
public:
    Image() = default;
    Image(Extent extent, Format format);
    Image(int width, int height, Format format) : Image(Extent{width, height}, format) {}

    const ImageView& view() const { return view_; }
    operator const ImageView&() const { return view_; }
    int width() const { return view_.width(); }
    int height() const { return view_.height(); }
    Extent extent() const { return view_.extent; }
    Format format() const { return view_.format; }
    float* channel(int c) const { return view_.channel(c); }
    float& at(int c, int x, int y) const { return view_.at(c, x, y); }
    int32_t& atInt(int x, int y) const { return view_.atInt(x, y); }
    void fill(float value);

private:
    std::array<PlaneStorage, 4> storage_;
    ImageView view_;
};

}  // namespace kestrel
