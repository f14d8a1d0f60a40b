#pragma once
// Display transforms: tone curves and the sRGB encoding, one implementation for the ToneMap pass,
// the EXR writer's PNG previews and the metrics of `kestrel compare` / `kestrel bench`
// (src/eval). They live beside the passes, not in the engine's public headers: which curves
// exist, where they saturate and how a display encodes values is viewing policy that the engine
// has no use for. Inline: the ToneMap pass calls them per pixel.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace kestrel::display {

/// Tone curves, in the order of toneCurveNames().
enum class ToneCurve { Reinhard, Aces, Clamp };

/// The curves' names as enum parameters declare them (index = ToneCurve value).
inline std::vector<std::string> toneCurveNames() {
    return {"reinhard", "aces", "clamp"};
}

/// Above this a linear value is white under every curve (the ToneMap pass and the previews):
/// clamping first keeps the rational curves free of Inf/Inf.
inline constexpr float kSaturation = 1e6f;

/// Display value in [0, 1] of a linear value: NaN, negatives and zero give 0; values above
/// `saturation` are taken as `saturation` (Aces needs one below 1e19: its products overflow).
inline float toneMap(float x, ToneCurve curve, float saturation = kSaturation) {
    if (!(x > 0.f)) return 0.f;
    x = std::min(x, saturation);
    switch (curve) {
        case ToneCurve::Reinhard:
            return x / (1.f + x);  // Reinhard et al. 2002, eq. 3, per channel
        case ToneCurve::Aces: {
            // Narkowicz 2015, "ACES Filmic Tone Mapping Curve" (fit of the ACES RRT + ODT).
            const float v = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
            return std::clamp(v, 0.f, 1.f);
        }
        case ToneCurve::Clamp:
            return std::min(x, 1.f);
    }
    return 0.f;
}

/// sRGB transfer function (IEC 61966-2-1) of a value clamped to [0, 1].
inline float srgbEncode(float x) {
    x = std::clamp(x, 0.f, 1.f);
    return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.f / 2.4f) - 0.055f;
}

/// Its inverse, for display values in [0, 1] (8- and 16-bit image files).
inline float srgbDecode(float v) {
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

/// A plain 2.2 display gamma of a value in [0, 1] (the metrics' Reinhard, src/eval/Metrics.h).
inline float gamma22Encode(float x) {
    return std::pow(x, 1.0f / 2.2f);
}

}  // namespace kestrel::display
