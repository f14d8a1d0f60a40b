#pragma once
// Counter-based random numbers: every value is a hash of (seed, frame, pixel, sample, stream,
// dimension), so images do not depend on the thread count or the order pixels are rendered in.
#include <cstdint>

namespace kestrel::scenegen {

/// "lowbias32" integer hash (C. Wellons, "Prospecting for Hash Functions", 2018).
inline uint32_t hash32(uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

enum class Stream : uint32_t { Noisy = 0x6e6f6973u, Reference = 0x72656665u };

/// Key of one pixel's random streams (hashed once per pixel, not per sample).
inline uint32_t pixelKey(uint32_t seed, int frame, uint32_t pixel, Stream stream) {
    return hash32(seed ^ hash32(uint32_t(frame) ^ hash32(pixel ^ hash32(uint32_t(stream)))));
}

class Rng {
public:
    Rng(uint32_t pixelKey, uint32_t sample) : key_(hash32(pixelKey ^ hash32(sample))) {}
    /// Uniform in [0, 1): 24 random bits.
    float next() { return float(hash32(key_ + (dim_++) * 0x9E3779B9u) >> 8) * 0x1p-24f; }

private:
    uint32_t key_;
    uint32_t dim_ = 0;
};

}  // namespace kestrel::scenegen
