#pragma once
// KeepExact: where the render's own 1-spp colour is already exact, it is kept instead of the
// filtered one. A smooth mirror's view of a light or the sky is such a place: the one camera path
// reaches the emitter through near-specular bounces only (the loader's lightThroughMirror), and
// its radiance is the reference's. The filters there smear what moves in the reflection (the
// showroom's swinging lamp left a trail over the dusk sky in the mirror: those pixels, 7.9% of the
// frame, came out 25.9 dB against the 1-spp input's 35.2: docs/benchmarks.md). A pixel is kept
// only where its whole 3x3 window is such a view and the window's 1-spp luminances agree within
// `agreement` (2%: half-float rounding and a smooth gradient, nothing more): at 1 spp any
// sampling noise breaks that (glass, which reflects or transmits per sample; a slightly rough or
// curved chrome, where blender-street's 1-spp values are close but not the reference's), and so
// does the edge of what the mirror shows. Elsewhere the output is the filtered one, unchanged.
#include <kestrel/Kestrel.h>

class KeepExactPass final : public kestrel::Pass {
public:
    struct Params {
        /// Largest ratio of the brightest to the darkest 1-spp luminance in a kept pixel's 3x3.
        float agreement = 1.02f;
    };
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, rendered, mask;
        kestrel::OutputPort colorOut;  ///< the port `color`
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit KeepExactPass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
};
