#include "NotExr.h"

#include <cstring>

namespace kestrel::exr {

namespace {

/// The image format whose signature `head` starts with; nullptr for none known.
const char* imageFormat(const unsigned char* head, size_t size) {
    auto starts = [&](const char* sig, size_t n) {
        return size >= n && std::memcmp(head, sig, n) == 0;
    };
    if (starts("\x89PNG\r\n\x1a\n", 8)) return "PNG";
    if (starts("#?", 2)) return "Radiance HDR";  // #?RADIANCE, #?RGBE
    if (starts("II*\0", 4) || starts("MM\0*", 4)) return "TIFF";
    if (starts("\xff\xd8\xff", 3)) return "JPEG";
    return nullptr;
}

}  // namespace

std::string notExrMessage(const unsigned char* head, size_t size) {
    const char* format = imageFormat(head, size);
    if (!format) return "not an OpenEXR file (bad magic number)";
    return std::string("a ") + format + " image, not OpenEXR: " + format +
           " carries colour only, and the loader reads OpenEXR, whose layers give the denoisers "
           "depth, normals and motion beside the colour (from Blender: OpenEXR MultiLayer with "
           "the Depth, Normal and Vector passes, docs/blender.md); convert colour-only frames "
           "to EXR for a colour-only graph";
}

}  // namespace kestrel::exr
