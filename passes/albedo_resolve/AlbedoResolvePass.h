#pragma once
// AlbedoResolve: the albedo to demodulate and re-modulate by. With a pixel filter wider than a
// pixel (Blender's default 1.5 px), a 1-spp G-buffer is one jittered sample per pixel per frame,
// while the reference is the filtered average: modulating by this frame's sample puts its
// aliasing back. There the albedo is accumulated over frames like the illumination (reprojected
// history, blend weight max(alpha, 1/length)); on un-jittered G-buffers this frame's albedo is
// exact and passes through unchanged.
//
// Accumulation is on where the source states a pixel filter wider than a pixel (the reference
// is then anti-aliased: at 1 spp Cycles still samples the G-buffer near pixel centres, so only
// an albedo averaged over the reprojected footprints of several frames approaches the filtered
// one), or where the depth itself jitters. The depth jitter is measured on every frame: on a plane, 1/depth is
// linear in screen position, so its second difference vanishes at pixel centres and is of the
// order of the first difference when every sample sits at a random point of its pixel. The
// score is the median of |second difference| / |first difference| over surface pixels.
#include <kestrel/Kestrel.h>

class AlbedoResolvePass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit AlbedoResolvePass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

    /// The jitter score of a depth image (0 when it has too few surface pixels to tell).
    static float jitterScore(const kestrel::ImageView& depth);

private:
    float alpha_, maxHistory_, threshold_;
    std::string mode_;
    int lastDecision_ = -1;  ///< for logging a change once
};
