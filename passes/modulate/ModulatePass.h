#pragma once
// Modulate: color = illumination * max(albedo, floor) + emission + base, the inverse of
// Demodulate (SVGF, Schied et al. 2017, section 4). `base` sums separately filtered components
// (diffuse + specular, direct + indirect).
#include <kestrel/Kestrel.h>

class ModulatePass final : public kestrel::Pass {
public:
    struct Params {
        float albedoFloor = 1e-3f;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort illumination, albedo, emission, base;
        kestrel::OutputPort color;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit ModulatePass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
};
