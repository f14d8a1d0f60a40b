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
    enum class Filter { Bilinear, CatmullRom };
    enum class DepthPrediction { Camera, None };
    struct Params {
        Filter filter = Filter::Bilinear;
        float depthThreshold = 10.f;
        DepthPrediction depthPrediction = DepthPrediction::Camera;
        float normalThreshold = 16.f;
        bool geometryTests = true;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort depth, normal, objectId, motion, position;
        kestrel::InputPort prevDepth, prevNormal, prevObjectId, prevColor, prevMoments,
            prevHistoryLength, sharedTaps;
        kestrel::OutputPort color, moments, historyLength, resampleBlur, taps;
    };
    static const Declaration& declaration();

    /// What a frame's reprojection takes from the parameters and the compiled graph.
    struct Settings {
        bool catmullRom;
        bool
            cameraDepth;  ///< predict last frame's depth with the fitted camera model (motion path)
        float depthThreshold, normalThreshold;  ///< infinite without the geometry tests
        float depthPrecision = 0.f;  ///< relative step of the stored depth (kDepthPrecisionFact)
    };

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit ReprojectionPass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Settings s_;
};
