#pragma once
// One iteration of the edge-avoiding A-Trous wavelet filter of SVGF (Schied et al. 2017,
// section 4.4, eq. 1-5). A graph chains instances with step 1, 2, 4, 8, 16.
#include <kestrel/Kestrel.h>

class ATrousPass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit ATrousPass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;
    std::string fusionKey() const override;
    void executeFused(kestrel::FrameContext& ctx, std::span<kestrel::Pass* const> passes,
                      std::span<kestrel::PassIO* const> ios) override;

    struct Settings {
        int step = 1;
        float sigmaZ = 1.f, sigmaN = 128.f, sigmaL = 4.f, sigmaColor = 0.6f;
        float depthPrecision = 0.f;  ///< relative step of the stored depth (kDepthPrecisionFact)
    };

private:
    Settings s_;
    bool exact_ = false;
    bool skipped_ = false;       // iteration >= iterations: passes its input through
    bool varianceBound_ = true;  // resolve: a pair fuses only with the same
};
