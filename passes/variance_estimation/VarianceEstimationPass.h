#pragma once
// SVGF variance estimation (Schied et al. 2017, section 4.2; Falcor SVGFFilterMoments): where the
// temporal history is short (< 4 frames) the temporal variance is unreliable, so the luminance
// moments are estimated spatially with a 7x7 cross-bilateral filter and the variance is boosted
// by 4 / historyLength; the illumination is filtered with the same weights there. Two chains
// on the same G-buffer run as a pair (executeFused): each tap weighed once for both.
#include <kestrel/Kestrel.h>

class VarianceEstimationPass final : public kestrel::Pass {
public:
    struct Params {
        float sigmaZ = 1.f;
        float sigmaN = 128.f;
        float sigmaL = 0.f;  ///< 0: no luminance term
        float minHistoryLength = 4.f;
        bool exact = false;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, moments, historyLength, variance, depth, normal, objectId;
        kestrel::OutputPort colorOut, varianceOut;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit VarianceEstimationPass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;
    /// Non-empty where the pass may run fused: without a luminance term (the default) a tap's
    /// weight depends on the geometry alone, so two chains' estimates share it.
    std::string fusionKey() const override;
    void executeFused(kestrel::FrameContext& ctx, std::span<kestrel::Pass* const> passes,
                      std::span<kestrel::PassIO* const> ios) override;

private:
    Params p_;
};
