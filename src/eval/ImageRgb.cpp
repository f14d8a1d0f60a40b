// References and outputs that are not EXR (PNG, Radiance HDR, TIFF, ...) through OpenImageIO,
// for `kestrel compare`, `run --reference` and `bench --reference` (eval/ExrRgb.h). OpenImageIO
// lives in the module kestrel_oiio (OiioModule.cpp), opened here on first use.
#include <kestrel/Error.h>
#include <kestrel/Plugin.h>

#include <cmath>
#include <memory>
#include <mutex>
#include <string>

#include "display/ToneMap.h"
#include "eval/ExrRgb.h"

namespace kestrel::eval {

namespace {

using ReadFn = float* (*)(const char*, int*, int*, int*, int*, char*, size_t);
using FreeFn = void (*)(float*);

struct Module {
    ReadFn read = nullptr;
    FreeFn free = nullptr;
    std::string why;  ///< why there is none
};

/// kestrel_oiio beside the plugin folder (<libdir>/kestrel/), opened once.
const Module& oiioModule() {
    static Module module;
    static std::once_flag once;
    std::call_once(once, [] {
        const HelperModule m = openHelperModule("kestrel_oiio.so");
        if (!m.handle) {
            module.why = "this build has no OpenImageIO module (" + m.error +
                         "; install libopenimageio-dev and rebuild)";
            return;
        }
        module.read = reinterpret_cast<ReadFn>(m.symbol("kestrel_oiio_read"));
        module.free = reinterpret_cast<FreeFn>(m.symbol("kestrel_oiio_free"));
        if (!module.read || !module.free) module.why = m.path.string() + " lacks its entry points";
    });
    return module;
}

}  // namespace

Image readImageRgb(const std::filesystem::path& path) {
    const std::string where = "'" + path.string() + "'";
    const Module& m = oiioModule();
    if (!m.read) throw FrameError(where + ": not an EXR, and " + m.why);
    int w = 0, h = 0, n = 0, integer = 0;
    char err[512] = {0};
    std::unique_ptr<float, FreeFn> pixels(
        m.read(path.c_str(), &w, &h, &n, &integer, err, sizeof err), m.free);
    if (!pixels) throw FrameError("cannot read image " + where + ": " + err);
    if (w <= 0 || h <= 0 || (n != 1 && n < 3))
        throw FrameError(where + ": expected an RGB or grey image, got " + std::to_string(n) +
                         " channel(s) of " + std::to_string(w) + "x" + std::to_string(h));
    // Integer files (PNG, 8/16-bit TIFF) are display-encoded sRGB; float ones (HDR, float
    // TIFF) scene-linear, as renderers write them.
    Image image(w, h, Format::Float3);
    for (size_t i = 0; i < size_t(w) * size_t(h); ++i)
        for (int c = 0; c < 3; ++c) {
            const float v = pixels.get()[i * size_t(n) + size_t(n == 1 ? 0 : c)];
            image.channel(c)[i] = integer ? display::srgbDecode(v) : v;
        }
    return image;
}

}  // namespace kestrel::eval
