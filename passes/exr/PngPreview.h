#pragma once
// 8-bit sRGB PNG previews of HDR images: exposure, a tone curve, the sRGB transfer function.
#include <string>

#include "OcioView.h"
#include "display/ToneMap.h"
#include "kestrel/Image.h"

namespace kestrel::exr {

/// Writes `image` (1-4 float channels or Int32 ids as hashed colours) to `path` as RGB8 PNG:
/// through `view` (the user's OpenColorIO display and view) where given, else the tone curve `op`
/// and sRGB (display/ToneMap.h). Throws Error naming the file.
void writePngPreview(const ImageView& image, const std::string& path, float exposureStops,
                     display::ToneCurve op, const OcioView* view = nullptr);

}  // namespace kestrel::exr
