#pragma once
// Small hand-made G-buffers for the SVGF pass tests.
#include <kestrel/Image.h>
#include <kestrel/testing/PassHarness.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>

namespace svgftest {

using kestrel::Format;
using kestrel::Image;

inline Image constant(int w, int h, Format f, float v) {
    Image im(w, h, f);
    im.fill(v);
    return im;
}

/// Grey Float3 image from f(x, y).
inline Image grey(int w, int h, const std::function<float(int, int)>& f) {
    Image im(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) im.at(c, x, y) = f(x, y);
    return im;
}

inline Image scalar(int w, int h, const std::function<float(int, int)>& f) {
    Image im(w, h, Format::Float);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) im.at(0, x, y) = f(x, y);
    return im;
}

inline Image normals(int w, int h, float nx, float ny, float nz) {
    Image im(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            im.at(0, x, y) = nx;
            im.at(1, x, y) = ny;
            im.at(2, x, y) = nz;
        }
    return im;
}

inline Image ids(int w, int h, const std::function<int(int, int)>& f) {
    Image im(w, h, Format::Int32);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) im.atInt(x, y) = f(x, y);
    return im;
}

/// Deterministic pseudo-random value in [0, 1) for pixel (x, y) and a seed.
inline float hash01(int x, int y, int seed = 0) {
    uint32_t h = uint32_t(x) * 73856093u ^ uint32_t(y) * 19349663u ^ uint32_t(seed) * 83492791u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return float(h & 0xffffff) / float(0x1000000);
}

inline Image clone(const Image& src) {
    Image im(src.extent(), src.format());
    int planes = std::max(1, kestrel::channelCount(src.format()));
    for (int c = 0; c < planes; ++c)
        std::memcpy(im.channel(c), src.channel(c), src.extent().pixels() * sizeof(float));
    return im;
}

inline bool allFinite(const Image& im) {
    for (int c = 0; c < kestrel::channelCount(im.format()); ++c)
        for (int y = 0; y < im.height(); ++y)
            for (int x = 0; x < im.width(); ++x)
                if (!std::isfinite(im.at(c, x, y))) return false;
    return true;
}

}  // namespace svgftest
