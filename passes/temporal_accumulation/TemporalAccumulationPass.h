#pragma once
// SVGF temporal accumulation (Schied et al. 2017, section 4.1-4.2): exponential moving average
// of the illumination and of the luminance moments (l, l^2) over the reprojected history, with
// alpha = max(alpha, 1 / historyLength) so young histories average uniformly; the per-pixel
// variance max(0, m2 - m1^2) drives the A-Trous luminance weight.
#include <kestrel/Kestrel.h>

#include "FireflySpread.h"

class TemporalAccumulationPass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit TemporalAccumulationPass(const kestrel::ParamValues& p);
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    float alpha_, momentsAlpha_, maxHistory_, fireflySigma_;
    kestrel::firefly::SpreadSettings spread_;
    kestrel::firefly::Excess excess_;  ///< this frame's clamped excess (only when spreading)
};
