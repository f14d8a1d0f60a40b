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
    struct Params {
        float alpha = 0.2f;
        float k = 1.f;
        int radius = 3;
        bool holdCurrent = false;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        InputPort color, history, historyLength;
        OutputPort colorOut;
    };
    static const Declaration& declaration();

    static PassDesc describe() { return declaration().desc(); }
    explicit ClampedAccumulationPass(const ParamValues& params) : p_(declaration().read(params)) {}
    void resolve(ResolveContext& rc) override;
    void execute(FrameContext& ctx, PassIO& io) override;

private:
    Params p_;
};

}  // namespace kestrel::passes
