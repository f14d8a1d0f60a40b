#pragma once
// Demodulate: illumination = (color - emission) / max(albedo, floor) per channel
// (SVGF, Schied et al. 2017, section 4: filter untextured illumination, re-apply albedo later).
#include <kestrel/Kestrel.h>

class DemodulatePass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit DemodulatePass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    float albedoFloor_;
};
