// In-memory PNG encoding (libpng) and base64 for data URIs in the bench report.
#include <kestrel/Error.h>
#include <png.h>

#include <cmath>
#include <string>
#include <vector>

#include "ReportUtil.h"
#include "eval/BenchReport.h"

namespace kestrel::eval {
namespace {

void appendBytes(png_structp png, png_bytep data, png_size_t length) {
    auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
    out->insert(out->end(), data, data + length);
}

}  // namespace

std::vector<unsigned char> encodePng(const ImageView& rgb, ToneMap toneMapKind) {
    Image safe = sanitizedRgb(rgb, nullptr, "PNG image");
    Image display = toneMapped(safe, toneMapKind);
    const int w = display.width(), h = display.height();
    std::vector<unsigned char> out;
    if (w <= 0 || h <= 0) throw Error("cannot encode an empty image as PNG");
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    if (!info) {
        png_destroy_write_struct(&png, nullptr);
        throw Error("libpng: out of memory");
    }
    std::vector<unsigned char> row(size_t(w) * 3);
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        throw Error("libpng: encoding failed");
    }
    png_set_write_fn(png, &out, appendBytes, nullptr);
    png_set_IHDR(png, info, png_uint_32(w), png_uint_32(h), 8, PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c)
                row[size_t(x) * 3 + c] =
                    (unsigned char)std::lround(255.0f * display.at(c, x, y));  // in [0, 1]
        png_write_row(png, row.data());
    }
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    return out;
}

std::string base64(const std::vector<unsigned char>& bytes) {
    static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string s;
    s.reserve((bytes.size() + 2) / 3 * 4);
    for (size_t i = 0; i < bytes.size(); i += 3) {
        const unsigned v = unsigned(bytes[i]) << 16 |
                           (i + 1 < bytes.size() ? unsigned(bytes[i + 1]) << 8 : 0u) |
                           (i + 2 < bytes.size() ? unsigned(bytes[i + 2]) : 0u);
        s += table[(v >> 18) & 63];
        s += table[(v >> 12) & 63];
        s += i + 1 < bytes.size() ? table[(v >> 6) & 63] : '=';
        s += i + 2 < bytes.size() ? table[v & 63] : '=';
    }
    return s;
}

}  // namespace kestrel::eval
