// PNGs of linear images for the bench report's data URIs (through the shared encoder,
// display/Png.h) and base64.
#include "display/Png.h"

#include <cstdint>
#include <string>
#include <vector>

#include "ReportUtil.h"
#include "eval/BenchReport.h"

namespace kestrel::eval {

std::vector<unsigned char> encodePng(const ImageView& rgb, ToneMap toneMapKind) {
    Image safe = sanitizedRgb(rgb, nullptr, "PNG image");
    const Image shown = toneMapped(safe, toneMapKind);
    const int w = shown.width(), h = shown.height();
    std::vector<uint8_t> pixels(size_t(w) * size_t(h) * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c)
                pixels[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c)] =
                    display::to8(shown.at(c, x, y));
    // No sRGB chunk: the metrics' displays are gamma 2.2 or linear as often as sRGB.
    return display::encodePng(pixels.data(), w, h, /*srgb=*/false);
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
