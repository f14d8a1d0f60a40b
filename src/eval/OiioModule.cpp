// kestrel_oiio: the one place OpenImageIO is linked, a module that readImageRgb (ImageRgb.cpp)
// opens with dlopen only when a file is not EXR. Linked into the kestrel binary, OpenImageIO's
// own dependencies (ffmpeg's codecs, ...) were loaded at every start: a run under a tight
// address-space limit no longer started.
#include <OpenImageIO/imageio.h>

#include <cstdlib>
#include <cstring>
#include <string>

namespace {
void setError(char* err, size_t size, const std::string& what) {
    if (size == 0) return;
    std::strncpy(err, what.c_str(), size - 1);
    err[size - 1] = '\0';
}
}  // namespace

/// The pixels of `path` as `*channels` interleaved floats per pixel (malloc'd; free with
/// kestrel_oiio_free), with whether the file stores integers (display-encoded); null and a
/// message in `err` on failure.
extern "C" float* kestrel_oiio_read(const char* path, int* width, int* height, int* channels,
                                    int* integer, char* err, size_t errSize) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        setError(err, errSize, OIIO::geterror());
        return nullptr;
    }
    const OIIO::ImageSpec& spec = in->spec();
    *width = spec.width;
    *height = spec.height;
    *channels = spec.nchannels;
    *integer = spec.format.is_floating_point() ? 0 : 1;
    const size_t n = size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels);
    auto* pixels = static_cast<float*>(std::malloc(n * sizeof(float)));
    if (!pixels || !in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels)) {
        setError(err, errSize, pixels ? in->geterror() : "out of memory");
        std::free(pixels);
        return nullptr;
    }
    return pixels;
}

extern "C" void kestrel_oiio_free(float* pixels) {
    std::free(pixels);
}
