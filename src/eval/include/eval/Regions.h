#pragma once
// Error per region of the frame. A filter that improves the frame on average can still ruin a
// region (a black sky, a smeared emitter): each region's error is measured for the output and for
// the 1-spp input it was made from, so "no region worse than the input" is a number, not a look.
//
// Regions come from the G-buffer as the ExrLoader reads it (any layout it reads), never from the
// reference. A pixel may be in several regions; "all" holds every pixel.
//   background   depth >= 1e9 (Conventions.h: 1e10), else objectId -1 (sky, environment)
//   emissive     not background, emission luminance > 1e-3
//   glossy       not background, specular albedo brighter than the diffuse albedo (metal, mirror)
//   textured     not background nor emissive, albedo luminance varies over the 3x3 neighbours on
//                the same object by more than 25% of its maximum
//   disoccluded  not background, no 2x2 tap of its motion-vector footprint in the previous frame
//                is on screen with the same object id and a depth within 10% (needs motion and
//                the previous frame; never on a sequence's first frame)
//   flat         none of the above (nor glossy at all: specular albedo luminance <= 0.02), and its
//                3x3 neighbours on screen, on one plane of the same object (inverse depth linear
//                within 1%), with albedo within 1%, in this frame and (where given) the one
//                before (where the reference's own noise is measured: ReferenceNoise)
//   reflection   not background, the loader's reflection output set: the pixel's features
//                describe what a near-specular surface shows (Blender: Cycles' Denoising Normal
//                names another surface than the Normal pass, or none), so a mirror's or a
//                polished floor's reflections are measured on their own
#include <kestrel/Image.h>
#include <kestrel/Registry.h>

#include <array>
#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "eval/Metrics.h"

namespace kestrel::eval {

enum Region : int {
    kAll,
    kBackground,
    kEmissive,
    kGlossy,
    kTextured,
    kDisoccluded,
    kFlat,
    kReflection,
    kRegionCount
};
const char* regionName(int region);

/// The loader outputs regions are made from, as planar floats (empty where the scene lacks it).
struct GBuffer {
    int width = 0, height = 0;
    std::vector<float> depth, emissionLum, albedoLum, specularLum, motionX, motionY, reflection;
    std::vector<int32_t> objectId;
    Image color;  ///< the 1-spp input colour (Float3)
};

/// Per-pixel membership: masks[region][pixel].
using RegionMasks = std::array<std::vector<uint8_t>, kRegionCount>;
/// `previous` is the G-buffer of the frame before (nullptr on the first: nothing disoccluded).
RegionMasks classifyRegions(const GBuffer& current, const GBuffer* previous);

/// Reads G-buffers frame by frame through the ExrLoader plugin (so every layout it reads works).
class GBufferReader {
public:
    /// `inputPattern` as `kestrel run --input`; `firstFrame` probes the layout. Throws Error.
    GBufferReader(const Registry& registry, const std::string& inputPattern, int64_t firstFrame);
    ~GBufferReader();
    GBuffer read(int64_t frame);
    /// Which outputs the scene provides ("depth", "objectId", ...), for reports.
    const std::vector<std::string>& provided() const;
    /// Whether the loader takes the render as anti-aliased (it offers jittered albedos).
    bool antiAliased() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// One frame's display values (tone-mapped output and reference), kept for the next frame's
/// temporal term.
struct DisplayFrame {
    Image out, ref;
};

/// Whether (x, y) and its 3x3 neighbours lie on one plane with one albedo: on screen, the same
/// object, albedo within 1%, inverse depth linear within 1%, none glossy nor emissive.
bool flatAround(const GBuffer& g, int x, int y);

/// The reference's own frame-to-frame noise, estimated on flat pixels: the part of temporal
/// instability (Metrics.h: temporalError, the output's change against the reference's) that no
/// output can remove. For the reference's change n (symmetric: a difference of two frames' noise)
/// and an output error a independent of it, (|a + n| + |a - n|) / 2 >= |n|, so E|a + n| >= E|n|:
/// no output scores below E|n_t - n_t-1| there.
///
/// The estimate: on a flat diffuse surface, shading moves with the surface, so d = r_t -
/// bilinear(r_t-1 at the motion vector) holds noise and what the lighting itself changes;
/// d - mean of its 8 neighbours (the same motion for all nine) removes any locally linear change
/// and leaves noise of variance sigma^2 (9/8 + sum c^2), c the bilinear weights convolved with that
/// high-pass. Scaled by sqrt(2 / (9/8 + sum c^2)) its mean magnitude is E|n_t - n_t-1| for noise
/// independent per pixel and Gaussian. What it assumes, and how it errs otherwise: a heavier tail
/// (fireflies) reads a few % high; lighting detail sharper than the bilinear resampling keeps
/// (a shadow edge under sub-pixel motion) counts as noise, high; noise correlated between
/// neighbours (an anti-aliased reference: a pixel filter wider than a pixel) reads low, so
/// compareRegions leaves it out on such renders. Checked against two references of the same zoo
/// scene rendered with different seeds, on the same pixels (`scripts/flicker-floor.sh --check`):
/// room 0.01087 estimated / 0.01083 measured, street-static 0.00448 / 0.00442, street 0.00766 /
/// 0.00722 (sunlit, moving camera: +6%).
struct ReferenceNoise {
    double floorSum = 0, outputSum = 0;
    uint64_t samples = 0;  ///< pixel-channels measured

    /// Adds the flat pixels of frame t (`flat`: its kFlat mask) whose motion is uniform over their
    /// 3x3 neighbours and whose bilinear footprint in frame t-1 is flat on the same surface.
    void add(const DisplayFrame& now, const DisplayFrame& before, const GBuffer& g,
             const GBuffer& prev, const std::vector<uint8_t>& flat);
    bool measured() const { return samples > 0; }
    /// E|n_t - n_t-1| over the measured pixels: about the least temporal instability there.
    double floor() const { return floorSum / double(std::max<uint64_t>(samples, 1)); }
    /// The output's temporal instability over the same pixels.
    double output() const { return outputSum / double(std::max<uint64_t>(samples, 1)); }
};

/// Sums of squared display-value errors per region, over frames, and of the output's temporal
/// instability (Metrics.h: temporalError) over the region's pixels in frame t.
struct RegionStats {
    std::array<double, kRegionCount> outSse{}, inSse{};
    std::array<uint64_t, kRegionCount> samples{};  ///< pixel-channels
    std::array<uint64_t, kRegionCount> framesWith{};
    std::array<double, kRegionCount> temporalSum{};
    std::array<uint64_t, kRegionCount> temporalSamples{};  ///< pixel-channels
    std::array<uint64_t, kRegionCount> speckleCount{};     ///< pixels (Metrics.h: speckleMask)
    ReferenceNoise noise;  ///< the reference's own flicker on flat pixels (compareRegions)

    /// Adds one frame: output, reference and input are linear RGB, tone-mapped here. With
    /// `previous` (the frame before's display values) the temporal terms too. Returns this
    /// frame's display values.
    DisplayFrame add(const ImageView& out, const ImageView& ref, const ImageView& input,
                     const RegionMasks& masks, ToneMap toneMap = ToneMap::Reinhard,
                     const DisplayFrame* previous = nullptr);
    bool has(int region) const { return samples[size_t(region)] > 0; }
    bool hasTemporal(int region) const { return temporalSamples[size_t(region)] > 0; }
    /// Mean temporal instability of the output over the region (which pixels flicker).
    double temporal(int region) const;
    /// Pixels the reference's noise was measured on, as a share of those with a temporal term.
    double referenceNoiseShare() const;
    /// Reported from 1% of the frame on: a few pixels under a moving shadow or reflection would
    /// count the light's own change as noise (blender-street: 16 flat pixels).
    bool reportsReferenceNoise() const { return referenceNoiseShare() >= 0.01; }
    /// Speckles per megapixel of the region (per frame: over every frame's pixels in it).
    double speckles(int region) const;
    double outPsnr(int region) const;
    double inPsnr(int region) const;
    /// Output MSE over input MSE (< 1: the filter helped there).
    double ratio(int region) const;
    /// Output MSE above the input's by more than kMseSlack: rounding (a region passed through
    /// unchanged, such as emission added back, or a float sky written and read again) is not.
    bool worseThanInput(int region) const;
    /// 1e-6 of a squared display value in [0, 1] (PSNR 60 dB): invisible, and far below any real
    /// regression (a black sky: MSE 0.44 there).
    static constexpr double kMseSlack = 1e-6;
};

/// Compares an output sequence with its reference per region, taking the G-buffer and the 1-spp
/// input from `inputPattern`. Throws Error / FrameError naming the file.
RegionStats compareRegions(const Registry& registry, const std::string& outPattern,
                           const std::string& refPattern, const std::string& inputPattern,
                           const std::vector<int64_t>& frames, ToneMap toneMap = ToneMap::Reinhard);

std::string formatRegionTable(const RegionStats& stats);
nlohmann::json regionsToJson(const RegionStats& stats);

}  // namespace kestrel::eval
