#pragma once
// The energy-keeping half of TemporalAccumulation's firefly clamp. The clamp takes off a sample
// what lies above its neighbours' and history's bound. Where that is a noise tail, dropping it
// lowers the error; where it is a large share of the light around it (a lamp the 1-spp frames
// reach only by rare BSDF samples), dropping it leaves the light missing for good, since the
// history is built from clamped frames (docs/benchmarks.md, section 7: the firefly clamp's bias).
// Here that share of the excess is scattered over the same surface around the sample, fading
// with distance (object id, normal and depth), so the image keeps its energy without keeping
// the firefly.
#include <kestrel/Kestrel.h>

#include <vector>

namespace kestrel::firefly {

/// The G-buffer the scatter stays on. objectId may be null.
struct Surface {
    const ImageView* depth;
    const ImageView* normal;
    const ImageView* objectId;
};

/// What one pixel receives from one sample at most, in units of the sample's clamp bound (both
/// as they enter the accumulation): two in-bound samples' worth. On the zoo's fireflies (svgf.json,
/// radius 15, frames 1-12) 19.97 dB at 1, 20.18 at 2, 20.29 at 4, 20.25 unheld; at 2 a sample of
/// 1e10 stays within the stability suite's bound of twice the ordinary range, where unheld it lit
/// its window at 1e7 (with an even share; ExtremeInputs.SinglePixelFireflies1e6To1e30).
constexpr float kMaxBoundsPerPixel = 2.f;

/// The largest radius: a window row's pixels are the bits of one 64-bit mask.
constexpr int kMaxRadius = 31;

struct SpreadSettings {
    int radius;       ///< the scatter's window is (2 radius + 1)^2 pixels
    float maxBounds;  ///< what one pixel receives from one sample, in units of its bound
    float fullShare;  ///< the clamped share of a window's light at which all of it is kept
};

/// What the clamp took off one sample: its colour times the weight the sample enters the
/// accumulation with, and the clamp's bound (luminance) times the same weight.
struct Clamped {
    int x;
    float e0, e1, e2, bound;
};

/// The clamped samples of one frame, row by row in x order: memory for the samples the clamp
/// took something off, not planes for the frame (a full-frame excess cost 25 B/px at 1080p).
struct Excess {
    std::vector<std::vector<Clamped>> rows;
    /// Empties every row for a frame of `height` rows, keeping their capacity.
    void reset(int height);
};

/// Adds to `color` (the accumulated colour, 3 planes) the kept part of `excess`: at each clamped
/// pixel q, the share f = min(1, E / (E + K) / fullShare), E and K the luminance of the excess and
/// of `color` summed over q's window (each term held to 1e8: a share beyond is 1 either way),
/// spread over the window's pixels on q's surface with a Gaussian falloff (sigma radius / 2), at
/// most maxBounds times q's clamp bound on any (a sample of 1e10 is no light to keep).
/// Deterministic and independent of the thread count (each output row sums in a fixed order).
void spreadExcess(const FrameContext& ctx, const Excess& excess, const Surface& surface,
                  SpreadSettings settings, const ImageView& color);

}  // namespace kestrel::firefly
