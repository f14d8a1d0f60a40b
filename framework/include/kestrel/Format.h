#pragma once
#include <cstdint>
#include <optional>
#include <string_view>

namespace kestrel {

/// Pixel format of an image resource. Images are planar: one 32-bit plane per channel.
enum class Format : uint8_t { Float, Float2, Float3, Float4, Int32, Any };

constexpr int channelCount(Format f) {
    switch (f) {
        case Format::Float: return 1;
        case Format::Float2: return 2;
        case Format::Float3: return 3;
        case Format::Float4: return 4;
        case Format::Int32: return 1;
        case Format::Any: return 0;
    }
    return 0;
}

std::string_view formatName(Format f);
std::optional<Format> parseFormat(std::string_view name);

/// Whether a resource of format `produced` may feed a port declared `accepted`.
constexpr bool formatAccepts(Format accepted, Format produced) {
    return accepted == Format::Any || accepted == produced;
}

struct Extent {
    int width = 0;
    int height = 0;
    bool operator==(const Extent&) const = default;
    size_t pixels() const { return size_t(width) * size_t(height); }
};

}  // namespace kestrel
