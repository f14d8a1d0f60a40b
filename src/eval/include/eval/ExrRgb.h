#pragma once
// A small EXR reader for comparisons: the R, G, B channels of one layer of a scanline or tiled
// EXR file (part 0), as a planar Float3 image of the data window's size.
#include <kestrel/Image.h>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace kestrel::eval {

/// Picks the RGB layer among a file's channel names. A layer is the prefix before ".R"/".G"/".B"
/// ("" for plain R, G, B); only prefixes with all three count. With `layer` empty: plain R,G,B if
/// present, else the single layer whose last component is "Combined" (Blender:
/// ViewLayer.Combined.R), else the only RGB layer there is. With `layer` given: the RGB layer equal
/// to it or ending in "." + layer ("Combined" finds "ViewLayer.Combined"). Returns the prefix;
/// throws kestrel::Error (without the file name) when none or several fit.
std::string chooseRgbLayer(const std::vector<std::string>& channelNames,
                           std::string_view layer = {});

/// Reads R, G, B (half, float or uint channels, converted to float). A file whose name does not
/// end in .exr is read by readImageRgb (`layer` unused). Throws kestrel::FrameError naming the
/// file when it is missing, unreadable or corrupt, or has no (unique) RGB layer.
Image readExrRgb(const std::filesystem::path& path, std::string_view layer = {});

/// A PNG, Radiance HDR, TIFF or other file OpenImageIO reads, as linear RGB: integer files are
/// taken as sRGB-encoded and decoded, float files as linear; a grey image gives R = G = B.
/// Throws kestrel::FrameError naming the file (also when this build has no OpenImageIO).
Image readImageRgb(const std::filesystem::path& path);

}  // namespace kestrel::eval
