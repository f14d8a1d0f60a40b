#pragma once
// One iteration of the edge-avoiding A-Trous wavelet filter of SVGF (Schied et al. 2017,
// section 4.4, eq. 1-5). A graph chains instances with step 1, 2, 4, 8, 16.
#include <kestrel/Kestrel.h>

class ATrousPass final : public kestrel::Pass {
public:
    struct Params {
        int step = 1;
        float sigmaZ = 1.f, sigmaN = 128.f, sigmaL = 4.f, sigmaColor = 0.6f;
        int iteration = 0;
        int iterations = 1024;
        bool exact = false;
    };
    /// What the kernels read: the parameters and what resolve learnt of the scene.
    struct Settings : Params {
        float depthPrecision = 0.f;  ///< relative step of the stored depth (kDepthPrecisionFact)
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, variance, depth, normal, objectId;
        kestrel::OutputPort colorOut, varianceOut;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit ATrousPass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;
    std::string fusionKey() const override;
    void executeFused(kestrel::FrameContext& ctx, std::span<kestrel::Pass* const> passes,
                      std::span<kestrel::PassIO* const> ios) override;

private:
    Settings s_;
    bool skipped_ = false;       // iteration >= iterations: passes its input through
    bool varianceBound_ = true;  // resolve: a pair fuses only with the same
};
