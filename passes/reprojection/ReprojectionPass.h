#pragma once
// Reprojection of last frame's history into this frame (SVGF, Schied et al. 2017, section 4.1;
// GAMES202 homework 5 for the matrix path). Finds each pixel's position in the previous frame
// (motion vectors, else world position + per-object and camera matrices, else identity), samples
// the history with a 2x2 bilinear footprint whose taps must pass consistency tests (on screen,
// same object id, depth and normal within tolerances scaled by their screen-space derivatives),
// falls back to a 3x3 box of consistent taps, else reports a disocclusion (history length 0).
#include <kestrel/Kestrel.h>

class ReprojectionPass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit ReprojectionPass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    bool catmullRom_;
    bool cameraDepth_;  ///< predict last frame's depth with the fitted camera model (motion path)
    float depthThreshold_, normalThreshold_;
    float depthPrecision_ = 0.f;  ///< relative step of the stored depth (kDepthPrecisionFact)
};
