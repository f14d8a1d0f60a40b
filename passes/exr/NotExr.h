#pragma once
// What a frame that is not OpenEXR is, for the one line that refuses it: image sequences written
// as PNG, Radiance HDR, TIFF or JPEG (a compositor's or viewer's export of a render) carry colour
// only, while the loader's outputs are the colour with its depth, normals, motion and albedo.
#include <cstddef>
#include <string>

namespace kestrel::exr {

/// The refusal of a file whose first bytes (`head`, `size` of them, at least 4 for a verdict) are
/// not OpenEXR's magic number: names the format when the bytes are a known image format's and
/// says what the loader needs instead; else "not an OpenEXR file (bad magic number)".
std::string notExrMessage(const unsigned char* head, size_t size);

}  // namespace kestrel::exr
