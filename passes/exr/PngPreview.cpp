#include "PngPreview.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "display/Png.h"
#include "kestrel/Error.h"

namespace kestrel::exr {

namespace {
/// errno as words ("No space left on device"); a write that failed without setting it says so.
std::string errnoReason() {
    return errno ? std::strerror(errno) : "the system gave no reason";
}
}  // namespace

namespace {
using display::to8;

/// A stable colour per object id (background -1: black).
void idColour(int32_t id, uint8_t rgb[3]) {
    if (id < 0) {
        rgb[0] = rgb[1] = rgb[2] = 0;
        return;
    }
    uint32_t h = uint32_t(id) * 2654435761u;  // Knuth's multiplicative hash
    h ^= h >> 15;
    rgb[0] = uint8_t(64 + (h & 0xBF));
    rgb[1] = uint8_t(64 + ((h >> 8) & 0xBF));
    rgb[2] = uint8_t(64 + ((h >> 16) & 0xBF));
}
}  // namespace

namespace {
/// Row y of `img` times `gain` as RGB triples (a single channel as grey, missing channels 0).
void linearRow(const ImageView& img, int y, float gain, std::vector<float>& row) {
    const int W = img.width(), C = img.channels();
    row.assign(size_t(W) * 3, 0.f);
    for (int x = 0; x < W; ++x)
        for (int c = 0; c < 3; ++c) {
            const int src = C == 1 ? 0 : c;
            if (src < C) row[size_t(x) * 3 + size_t(c)] = img.at(src, x, y) * gain;
        }
}

/// The 8-bit display pixels of `img`: ids as colours; colour through `view` or `op` and sRGB.
std::vector<uint8_t> displayPixels(const ImageView& img, float gain, display::ToneCurve op,
                                   const OcioView* view) {
    const int W = img.width(), H = img.height();
    std::vector<uint8_t> rgb(size_t(W) * size_t(H) * 3);
    std::vector<float> row;
    for (int y = 0; y < H; ++y) {
        uint8_t* p = &rgb[size_t(y) * size_t(W) * 3];
        if (img.format == Format::Int32) {
            for (int x = 0; x < W; ++x) idColour(img.atInt(x, y), p + size_t(x) * 3);
            continue;
        }
        linearRow(img, y, gain, row);
        if (view) {
            for (float& v : row) v = std::isnan(v) ? 0.f : v;  // OCIO passes NaN through
            view->apply(row.data(), size_t(W));
            for (size_t i = 0; i < row.size(); ++i) p[i] = to8(std::isnan(row[i]) ? 0.f : row[i]);
        } else {
            for (size_t i = 0; i < row.size(); ++i)
                p[i] = to8(display::srgbEncode(display::toneMap(row[i], op)));
        }
    }
    return rgb;
}
}  // namespace

void writePngPreview(const ImageView& img, const std::string& path, float exposureStops,
                     display::ToneCurve op, const OcioView* view) {
    const int W = img.width(), H = img.height();
    std::vector<uint8_t> rgb = displayPixels(img, std::exp2(exposureStops), op, view);

    std::vector<unsigned char> bytes;
    try {
        bytes = display::encodePng(rgb.data(), W, H, /*srgb=*/true);
    } catch (const Error& e) {
        throw Error("cannot write PNG " + path + ": " + e.what());
    }
    errno = 0;  // what the failing open or write sets is the reason the user is given
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) throw Error("cannot create PNG " + path + ": " + errnoReason());
    const bool written = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
    if (std::fclose(f) != 0 || !written)
        throw Error("cannot write PNG " + path + ": " + errnoReason());
}

}  // namespace kestrel::exr
