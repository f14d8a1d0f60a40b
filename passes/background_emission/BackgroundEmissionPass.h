#pragma once
// BackgroundEmission: the emission a filter leaves alone, with the background joined to it. A
// pixel whose G-buffer has no surface (depth at the background) shows the environment seen
// directly, which a path tracer looks up without sampling: its colour is exact at 1 spp. A render
// without an environment pass (Blender's usual set-up for denoising: Combined, Z, Normal, Vector,
// Denoising Data) otherwise sends its sky through demodulation and the spatial filters, which can
// only blur an exact value (blender-street-defaults, svgf-notaa.json: sky MSE 1.05x its input's).
#include <kestrel/Kestrel.h>

class BackgroundEmissionPass final : public kestrel::Pass {
public:
    struct Params {};
    /// Ports, declared once (kestrel/Declare.h); the pass has no parameters.
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, depth, emission;
        kestrel::OutputPort emissionOut;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit BackgroundEmissionPass(const kestrel::ParamValues&) {}
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;
};
