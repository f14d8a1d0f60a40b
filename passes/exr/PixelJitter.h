#pragma once
// Whether a render's pixels are point-sampled or filtered over more than a pixel (anti-aliased),
// decided once per run at compile time. With a pixel filter wider than a pixel the reference is
// the filtered average over neighbouring surfaces while a 1-spp frame holds one sample of it:
// its albedo must be averaged over frames before it re-modulates the filtered illumination.
#include <optional>
#include <string>

namespace kestrel::exr {

/// Above this depth jitter score a render counts as anti-aliased. Measured: point-sampled
/// renders score 5e-6 (scenegen street), 7e-5 (scenegen room 1080p) and 2.5e-4 (Blender, both
/// filter settings: Cycles samples its first pass near pixel centres); the scenegen street with
/// a 1.5 px Blackman-Harris filter scores 0.90.
constexpr float kJitterThreshold = 0.05f;

/// The median over surface pixels of |second difference| / |first difference| of 1/depth along
/// rows and columns (every other pixel). On a plane 1/depth is linear in screen position, so
/// the ratio vanishes at pixel centres and is of order 1 when each sample sits at a random point
/// of its footprint. 0 when fewer than 16 pixels can tell.
float depthJitterScore(const float* depth, int width, int height);

/// Blender's default pixel filter (Blackman-Harris), what a Blender render that states no filter
/// (no camera.json) is assumed to use: Cycles writes the depth of the first sample, at the pixel
/// centre, with any filter (the street renders score 2.5e-4 with 0.01 and 1.5 px alike), so the
/// depth cannot tell. Wrong either way costs: blender-street-defaults judged point-sampled 25.2
/// dB against 30.7, the 0.01 px blender-street judged anti-aliased 29.8 against 31.6 (svgf.json,
/// no camera.json); users who render for denoising usually keep the default.
constexpr float kBlenderDefaultFilterWidth = 1.5f;

/// The decision and its reason for the run log.
struct AntiAliasing {
    bool antiAliased = false;
    std::string why;
};
/// `stated`: the pixel filter width the source states (camera.json, kestrel.pixelFilterWidth);
/// `score`: depthJitterScore of the first frame, when the render does not state it.
AntiAliasing decideAntiAliasing(std::optional<float> stated, std::optional<float> score);
/// A Blender render that states no pixel filter: decided by `score` (depthJitterScore of the first
/// frame) when its samples are off pixel centres; when they are centred, or there is no depth,
/// the data cannot tell (Cycles centres the first sample with any filter: blender-street's
/// 0.01 px and 1.5 px renders' 1-spp frames agree to 3e-7 in depth, 8e-6 in colour, median
/// relative difference), and Blender's default is taken, the log saying so, with the score and
/// how to state the filter.
AntiAliasing decideBlenderAntiAliasing(std::optional<float> score);

}  // namespace kestrel::exr
