#pragma once
// Error metrics of an output image against a reference (docs/design.md section 7, "Measuring").
//
// Conventions (every metric uses them the same way):
// - Inputs are planar float images (Float3 or Float4; only R, G, B are used). Both images must
//   have the same extent.
// - Non-finite inputs are counted, never silently propagated: before any metric, NaN becomes 0
//   and +-Inf becomes +-FLT_MAX (so an Inf output shows up as a huge, finite relMSE). The counts
//   are reported next to the metrics (FrameMetrics::nonFiniteOutput / nonFiniteReference).
// - relMSE is computed on linear values: mean over pixels and R,G,B of (x - r)^2 / (r^2 + 1e-2).
// - PSNR, SSIM and temporal instability are computed on display values d = T(x) in [0, 1], with
//   T the chosen tone map (ToneMap below; default Reinhard with gamma 2.2:
//   d = clamp(x / (1 + x), 0, 1)^(1/2.2) per channel, negatives clamped to 0 first). This default
//   reproduces the 1-spp input's figures on the Blender sample room given in docs/design.md
//   section 7 (PSNR 15.6, SSIM 0.111).
// - PSNR = 10 log10(1 / MSE) over pixels and R,G,B, with MSE floored at 1e-10 (PSNR <= 100 dB,
//   so identical images give 100, not +inf, and means stay finite).
// - SSIM: Wang, Bovik, Sheikh, Simoncelli 2004, eq. 13 with an 11x11 Gaussian window, sigma 1.5,
//   K1 0.01, K2 0.03, L 1, computed per channel R,G,B and averaged (mean SSIM over all pixels and
//   channels). At the image border the window is truncated to the image and renormalised, so every
//   pixel counts and images smaller than the window work.
// - Temporal instability: mean over pixels and R,G,B of |(o_t - o_{t-1}) - (r_t - r_{t-1})| on
//   display values: zero when the output changes exactly as the reference does.
// - Speckles: isolated dark pixels a filter left behind, on linear luminance (Rec. 709): output
//   below 0.3x the reference, where the reference is not dark (above 5% of its frame mean) and
//   the output's own 3x3 median is above 2x the pixel. Reported per megapixel per frame.
#include <kestrel/Image.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace kestrel::eval {

/// The metrics' display transforms, by name (--tonemap): combinations of the shared tone curves
/// and encodings (display/ToneMap.h), not another implementation of them.
enum class ToneMap {
    /// (x / (1 + x))^(1/2.2): HDR highlights stay distinguishable, display gamma (default)
    Reinhard,
    Clamp,  ///< clamp(x, 0, 1), linear
    Srgb,   ///< sRGB OETF (IEC 61966-2-1) of clamp(x, 0, 1)
};
std::string_view toneMapName(ToneMap t);
/// "reinhard", "clamp", "srgb"; nullopt otherwise.
std::optional<ToneMap> parseToneMap(std::string_view name);
/// The display value of one linear value (NaN -> 0, +Inf -> 1).
float toneMap(ToneMap t, float x);

/// The numbers of one frame.
struct FrameMetrics {
    double relMse = 0;
    double psnr = 0;  ///< dB, <= 100
    double ssim = 0;
    /// Against the previous frame of the sequence; absent on the first frame.
    std::optional<double> temporal;
    double speckles = 0;            ///< speckles per megapixel (speckleMask)
    size_t nonFiniteOutput = 0;     ///< pixels of the output with a NaN/Inf in R, G or B
    size_t nonFiniteReference = 0;  ///< likewise in the reference
};

/// Sanitised R, G, B planes of an image: NaN -> 0, +-Inf -> +-FLT_MAX. `nonFinite` receives the
/// number of affected pixels. Throws kestrel::Error for a format with fewer than 3 channels.
Image sanitizedRgb(const ImageView& image, size_t* nonFinite = nullptr, const char* what = "image");
/// The tone-mapped R, G, B planes of a (sanitised) RGB image.
Image toneMapped(const ImageView& rgb, ToneMap t);

// The single metrics. Each requires equal extents and >= 3 channels (kestrel::Error otherwise)
// and expects finite values (sanitise first; compareImages does).
double relMse(const ImageView& out, const ImageView& ref);
/// PSNR of display values in [0, 1] (call toneMapped first).
double psnr(const ImageView& outDisplay, const ImageView& refDisplay);
/// Mean SSIM of display values in [0, 1].
double ssim(const ImageView& outDisplay, const ImageView& refDisplay);
/// One display value's temporal error |(o_t - o_prev) - (r_t - r_prev)|: zero when the output
/// changes exactly as the reference does.
inline double temporalError(float o, float oPrev, float r, float rPrev) {
    const double d = (double(o) - oPrev) - (double(r) - rPrev);
    return d < 0 ? -d : d;
}
/// Mean temporalError over pixels and R, G, B (display values).
double temporalInstability(const ImageView& out, const ImageView& outPrev, const ImageView& ref,
                           const ImageView& refPrev);

/// Which pixels are speckles (1) of a (sanitised) linear output against its reference: see the
/// conventions above. Requires equal extents.
std::vector<uint8_t> speckleMask(const ImageView& out, const ImageView& ref);
/// Speckles per megapixel of a mask from speckleMask.
double specklesPerMegapixel(const std::vector<uint8_t>& mask);

/// All metrics of one frame from raw images (sanitises and tone-maps internally). The previous
/// frame's display images, when given, produce FrameMetrics::temporal.
struct FrameImages {
    Image outDisplay, refDisplay;  ///< kept for the next frame's temporal term
};
FrameMetrics compareImages(const ImageView& out, const ImageView& ref, ToneMap toneMap,
                           const FrameImages* previous = nullptr, FrameImages* current = nullptr);

}  // namespace kestrel::eval
