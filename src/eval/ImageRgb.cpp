// References and outputs that are not EXR (PNG, Radiance HDR, TIFF, ...) through OpenImageIO,
// for `kestrel compare`, `run --reference` and `bench --reference` (eval/ExrRgb.h).
#include <kestrel/Error.h>

#include <cmath>
#include <string>
#include <vector>

#include "eval/ExrRgb.h"

#ifdef KESTREL_HAS_OIIO
#include <OpenImageIO/imageio.h>
#endif

namespace kestrel::eval {

namespace {

/// The sRGB transfer function inverted (IEC 61966-2-1): 8- and 16-bit files hold display values.
float srgbDecode(float v) {
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

}  // namespace

Image readImageRgb(const std::filesystem::path& path) {
    const std::string where = "'" + path.string() + "'";
#ifdef KESTREL_HAS_OIIO
    auto in = OIIO::ImageInput::open(path.string());
    if (!in) throw FrameError("cannot read image " + where + ": " + OIIO::geterror());
    const OIIO::ImageSpec& spec = in->spec();
    const int w = spec.width, h = spec.height, n = spec.nchannels;
    if (w <= 0 || h <= 0 || (n != 1 && n < 3))
        throw FrameError(where + ": expected an RGB or grey image, got " + std::to_string(n) +
                         " channel(s) of " + std::to_string(w) + "x" + std::to_string(h));
    std::vector<float> pixels(size_t(w) * size_t(h) * size_t(n));
    if (!in->read_image(0, 0, 0, n, OIIO::TypeDesc::FLOAT, pixels.data()))
        throw FrameError("cannot read image " + where + ": " + in->geterror());
    // Integer files (PNG, 8/16-bit TIFF) are display-encoded sRGB; float ones (HDR, float
    // TIFF) scene-linear, as renderers write them.
    const bool encoded = !spec.format.is_floating_point();
    Image image(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                const float v = pixels[(size_t(y) * size_t(w) + size_t(x)) * size_t(n) +
                                       size_t(n == 1 ? 0 : c)];
                image.channel(c)[size_t(y) * size_t(w) + size_t(x)] = encoded ? srgbDecode(v) : v;
            }
    return image;
#else
    throw FrameError(where +
                     ": not an EXR, and this build has no OpenImageIO to read it "
                     "(install libopenimageio-dev and rebuild)");
#endif
}

}  // namespace kestrel::eval
