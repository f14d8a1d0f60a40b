#pragma once
// 8-bit RGB PNG encoding: the one encoder of the EXR writer's previews (passes/exr) and the bench
// report's crops (src/eval), libpng at its default compression.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace kestrel::display {

/// The 8-bit code of a display value (clamped to [0, 1], rounded to nearest).
inline uint8_t to8(float v) {
    return uint8_t(std::lround(std::clamp(v, 0.f, 1.f) * 255.f));
}

/// A PNG file's bytes of `height` rows of `width` interleaved RGB triples. `srgb` marks the
/// values as sRGB-encoded (an sRGB chunk, perceptual intent): previews are, while the metrics'
/// displays (gamma 2.2, linear clamp) must not claim it. Throws kestrel::Error.
std::vector<unsigned char> encodePng(const uint8_t* rgb, int width, int height, bool srgb);

}  // namespace kestrel::display
