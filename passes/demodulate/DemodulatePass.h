#pragma once
// Demodulate: illumination = (color - emission) / max(albedo, floor) per channel
// (SVGF, Schied et al. 2017, section 4: filter untextured illumination, re-apply albedo later).
#include <kestrel/Kestrel.h>

class DemodulatePass final : public kestrel::Pass {
public:
    struct Params {
        float albedoFloor = 1e-3f;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, albedo, emission, objectId;
        kestrel::OutputPort illumination, albedoOut;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit DemodulatePass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
};
