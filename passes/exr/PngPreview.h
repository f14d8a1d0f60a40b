#pragma once
// 8-bit sRGB PNG previews of HDR images: exposure, a tone curve, the sRGB transfer function.
#include <string>

#include "OcioView.h"
#include "kestrel/Image.h"

namespace kestrel::exr {

enum class ToneMap { Aces, Reinhard, Clamp };

/// Display value in [0, 1] of a linear HDR value (NaN -> 0).
float toneMap(float linear, ToneMap op);
/// sRGB transfer function (IEC 61966-2-1) of a value in [0, 1].
float srgbEncode(float linear01);

/// Writes `image` (1-4 float channels or Int32 ids as hashed colours) to `path` as RGB8 PNG:
/// through `view` (the user's OpenColorIO display and view) where given, else the tone curve `op`
/// and sRGB. Throws Error naming the file.
void writePngPreview(const ImageView& image, const std::string& path, float exposureStops,
                     ToneMap op, const OcioView* view = nullptr);

}  // namespace kestrel::exr
