#include "kestrel/Format.h"

namespace kestrel {

std::string_view formatName(Format f) {
    switch (f) {
        case Format::Float: return "float";
        case Format::Float2: return "float2";
        case Format::Float3: return "float3";
        case Format::Float4: return "float4";
        case Format::Int32: return "int32";
        case Format::Any: return "any";
    }
    return "?";
}

std::optional<Format> parseFormat(std::string_view name) {
    for (Format f : {Format::Float, Format::Float2, Format::Float3, Format::Float4, Format::Int32,
                     Format::Any})
        if (formatName(f) == name) return f;
    return std::nullopt;
}

}  // namespace kestrel
