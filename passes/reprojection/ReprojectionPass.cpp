// The pass's declaration (ports and parameters), its settings and what it adapts to at compile
// time; the frame's work is Reproject.cpp's.
#include "ReprojectionPass.h"

#include <limits>

#include "Reproject.h"

using namespace kestrel;

ReprojectionPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "Reprojection",
          "Reprojects last frame's colour, moments and history length into this frame:"
          " position from motion vectors, else world position + per-object and camera"
          " matrices, else identity; 2x2 bilinear taps with depth/normal/id consistency"
          " tests, 3x3 fallback, else disocclusion (historyLength 0). Optional Catmull-Rom"
          " colour resampling for TAA histories.") {
    depth = input("depth", Format::Float, "linear view depth");
    normal = input("normal", Format::Float3, "world-space normal");
    objectId =
        optionalInput("objectId", Format::Int32, "object id (taps on another object are rejected)");
    motion = optionalInput("motion", Format::Float2, "screen motion to the previous frame, pixels");
    position = optionalInput("position", Format::Float3, "world position (matrix reprojection)");
    prevDepth = historyInput("prevDepth", Format::Float, "last frame's depth");
    prevNormal = historyInput("prevNormal", Format::Float3, "last frame's normal");
    prevObjectId = historyInput("prevObjectId", Format::Int32, "last frame's object id");
    prevColor = historyInput("prevColor", Format::Float3, "last frame's colour history");
    prevMoments = historyInput("prevMoments", Format::Float2, "last frame's moments history");
    prevHistoryLength =
        historyInput("prevHistoryLength", Format::Float, "last frame's history length");
    sharedTaps = optionalInput("sharedTaps", Format::Int32,
                               "another Reprojection's `taps` over the same geometry, motion and "
                               "thresholds (the specular chain takes the diffuse chain's): its "
                               "outcomes replace this pass's consistency tests, which are then not "
                               "run (a bilinear pass's taps hold no outer taps: Catmull-Rom then "
                               "resamples bilinearly); on a frame where a pixel is marked "
                               "untested (VirtualMotion moved its motion: denoise/TapsMask.h) "
                               "this pass tests with its own settings instead");
    color = output("color", Format::Float3, "reprojected colour (0 where disoccluded)");
    moments = output("moments", Format::Float2, "reprojected moments (0 where disoccluded)");
    historyLength = output("historyLength", Format::Float,
                           "reprojected history length, 0 where disoccluded or without valid "
                           "history; when prevHistoryLength is not fed, 1 where the reprojection "
                           "succeeded");
    resampleBlur = output("resampleBlur", Format::Float,
                          "how much resampling the history blurs it, in [0, 1]: 2 (fx (1 - fx) + "
                          "fy (1 - fy)) of the reprojected position's fractions fx, fy between "
                          "pixel centres (0 on a centre, 1 midway between four), 1 on the 3x3 "
                          "fallback, 0 where disoccluded (TAA weights the history down by it, "
                          "Karis 2014)");
    taps = output("taps", Format::Int32,
                  "which taps passed the consistency tests, a bit per tap (the 4x4 Catmull-Rom "
                  "footprint, the 3x3 fallback), for another reprojection's sharedTaps");
    param("filter", &Params::filter, {"bilinear", "catmullrom"},
          "colour resampling: bilinear (SVGF) or Catmull-Rom 4x4 (sharp, for TAA)");
    param("depthThreshold", &Params::depthThreshold, 0.0, 1e6,
          "max |z_expected - z_prev| / (fwidth(z) + 0.01) of a consistent tap");
    param("depthPrediction", &Params::depthPrediction, {"camera", "none"},
          "z_expected with motion vectors: camera (z_prev = z (a u + b v + c) + d, a pinhole "
          "camera's rigid motion fitted per frame to the motion vectors' correspondences, so a "
          "dollying camera keeps the history of surfaces facing it) or none (z itself, SVGF's "
          "test); the matrix path uses the matrices");
    param("normalThreshold", &Params::normalThreshold, 0.0, 1e6,
          "max |n - n_prev| / (fwidth(n) + 0.01) of a consistent tap");
    param("geometryTests", &Params::geometryTests,
          "the depth and normal tests (the object id and screen bounds are always tested); off "
          "for TAA histories on jittered G-buffers (a pixel filter wider than a pixel), where "
          "each frame's depth and normal are another sample of the footprint, the tests reject "
          "the edges TAA exists to accumulate, and TAA's neighbourhood clip rejects stale "
          "history instead (Karis 2014)");
}

const ReprojectionPass::Declaration& ReprojectionPass::declaration() {
    static const Declaration d;
    return d;
}

namespace {
ReprojectionPass::Settings settingsOf(const ReprojectionPass::Params& p) {
    // Without the geometry tests every tap passes them: an infinite threshold is passed by any
    // finite distance (and a NaN normal still fails, as with the tests).
    constexpr float kNoTest = std::numeric_limits<float>::infinity();
    return {p.filter == ReprojectionPass::Filter::CatmullRom,
            p.depthPrediction == ReprojectionPass::DepthPrediction::Camera,
            p.geometryTests ? p.depthThreshold : kNoTest,
            p.geometryTests ? p.normalThreshold : kNoTest};
}
}  // namespace

ReprojectionPass::ReprojectionPass(const ParamValues& p) : s_(settingsOf(declaration().read(p))) {}

void ReprojectionPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (!rc.isBound(d.prevColor)) rc.setAbsent(d.color, "prevColor is not connected");
    if (!rc.isBound(d.prevMoments)) rc.setAbsent(d.moments, "prevMoments is not connected");
    s_.depthPrecision = depthPrecision(rc);
    if (rc.isBound(d.sharedTaps)) {
        rc.setAbsent(d.taps, "the taps come from sharedTaps");
        rc.note(
            "consistency tests taken from sharedTaps (tested here on a frame with a pixel "
            "marked untested)");
    }
    if (rc.isBound(d.motion)) {
        rc.note("reprojecting with motion vectors");
        // World positions serve only the matrix path: not read, so the loader skips them.
        if (rc.isBound(d.position)) rc.ignoreInput(d.position, "motion vectors are given");
    } else if (rc.isBound(d.position))
        rc.note("reprojecting with world positions and matrices");
    else
        rc.note("no motion and no position: identity reprojection (static camera assumed)");
}

void ReprojectionPass::execute(FrameContext& ctx, PassIO& io) {
    reprojectFrame(ctx, io, s_);
}
