#pragma once
// TAA: temporal anti-aliasing / stabilisation of the current colour with its own reprojected
// previous output.
//   - history arrives already resampled (a Reprojection instance with filter "catmullrom", fed
//     by a history edge taa.color -> reproj.prevColor): bilinear resampling blurs, and the blur
//     accumulates frame after frame (docs/design.md section 6, reprojection);
//   - where historyLength is 0 (disocclusion) the history is dropped, not clipped: a clip box
//     on high-contrast texture is too wide to reject a ghost;
//   - the history is clipped (or clamped) in YCoCg to the current 3x3 neighbourhood's
//     mean +- gamma * sigma (variance clipping, Salvi 2016, "An Excursion in Temporal
//     Supersampling"; clip towards the mean as in Pedersen 2016, INSIDE), the box widened to
//     contain the current colour so that a static input is a fixed point;
//   - blend: out = alpha * C + (1 - alpha) * H, optionally with inverse-luminance weights
//     (Karis 2014, "High Quality Temporal Supersampling") so a bright outlier cannot flicker;
//   - alpha rises with the history's resampling blur (Reprojection's resampleBlur, Karis 2014):
//     history resampled between pixel centres blurs texture, and the blur accumulates (the
//     Blender sample room: 33.4 dB with the history at full weight, 35.9 with blurAlpha 1,
//     36.3 without TAA; anti-aliased renders gain from it too once their albedo is averaged
//     over frames);
//   - warmUp: historyLength is the pass's own age (its historyLength output fed back through
//     the reprojection), and the current frame weighs at least 2 / (n + 1) in a history of n
//     frames: an input that converges after a disocclusion (a denoiser's output) would
//     otherwise keep its first, worst frames in the blend for long;
//   - onlyAntiAliased leaves the pass out on point-sampled renders (the source's scene fact
//     antiAliased is not "true"): there
//     the reference is as sharp as each frame, and even the weighted history cost 0.03-0.35 dB
//     and raised the temporal instability on six of seven point-sampled sequences. On
//     anti-aliased renders svgf.json's TAA reprojection runs without the depth/normal tests,
//     which on a jittered G-buffer reject the edges TAA anti-aliases (Reprojection's
//     geometryTests).
#include <kestrel/Kestrel.h>

namespace kestrel::passes {

class TaaPass final : public Pass {
public:
    enum class Mode { Clip, Clamp };
    struct Params {
        float alpha = 0.1f;
        float blurAlpha = 1.f;
        float gamma = 1.f;
        Mode mode = Mode::Clip;
        bool onlyAntiAliased = false;
        bool warmUp = false;
        bool antiFlicker = true;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        InputPort color, history, historyLength, resampleBlur;
        OutputPort colorOut, historyLengthOut;
    };
    static const Declaration& declaration();

    static PassDesc describe() { return declaration().desc(); }
    explicit TaaPass(const ParamValues& params) : p_(declaration().read(params)) {}
    void resolve(ResolveContext& rc) override;
    void execute(FrameContext& ctx, PassIO& io) override;

private:
    Params p_;
};

}  // namespace kestrel::passes
