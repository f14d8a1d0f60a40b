#pragma once
// Modulate: color = illumination * max(albedo, floor) + emission + base, the inverse of
// Demodulate (SVGF, Schied et al. 2017, section 4). `base` sums separately filtered components
// (diffuse + specular, direct + indirect).
#include <kestrel/Kestrel.h>

class ModulatePass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit ModulatePass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    float albedoFloor_;
};
