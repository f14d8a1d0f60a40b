#pragma once
// ClampedAccumulation (GAMES202 homework 5, section 2.3): temporal blend of the current filtered
// colour with the reprojected previous output, the history first clamped to the current
// neighbourhood's mean +- k sigma so that stale history (lag, ghosts) is rejected:
//   C_i = alpha * C + (1 - alpha) * clamp(C_prev, mu - k sigma, mu + k sigma)
// mu and sigma per channel over a (2 radius + 1)^2 window of C (clipped at the image border);
// alpha = 1 where the reprojection failed (historyLength 0) or no history exists.
#include <kestrel/Kestrel.h>

namespace kestrel::passes {

class ClampedAccumulationPass final : public Pass {
public:
    static PassDesc describe();
    explicit ClampedAccumulationPass(const ParamValues& params);
    void resolve(ResolveContext& rc) override;
    void execute(FrameContext& ctx, PassIO& io) override;

private:
    float alpha_ = 0.2f;
    float k_ = 1.f;
    int radius_ = 3;
    bool holdCurrent_ = false;
};

}  // namespace kestrel::passes
