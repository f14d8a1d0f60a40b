#pragma once
// SVGF temporal accumulation (Schied et al. 2017, section 4.1-4.2): exponential moving average
// of the illumination and of the luminance moments (l, l^2) over the reprojected history, with
// alpha = max(alpha, 1 / historyLength) so young histories average uniformly; the per-pixel
// variance max(0, m2 - m1^2) drives the A-Trous luminance weight.
#include <kestrel/Kestrel.h>

#include "FireflySpread.h"

class TemporalAccumulationPass final : public kestrel::Pass {
public:
    struct Params {
        float alpha = 0.2f;
        float momentsAlpha = 0.2f;
        float maxHistoryLength = 32.f;
        float fireflySigma = 3.f;
        int fireflySpread = 0;          ///< FireflySpread.h
        float fireflyFullShare = 0.2f;  ///< FireflySpread.h
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, prevColor, prevMoments, prevHistoryLength, depth, normal,
            objectId;
        kestrel::OutputPort colorOut, moments, historyLength, variance;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit TemporalAccumulationPass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
    kestrel::firefly::Excess excess_;  ///< this frame's clamped samples (only when spreading)
};
