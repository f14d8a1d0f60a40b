#pragma once
// Mix: color = a + weight * (b - a), per channel. svgf-chain.json uses it for the colour history:
// between the temporal accumulation (a) and its first A-Trous iteration (b), which SVGF
// (Schied et al. 2017, section 4.3) feeds back whole. Weight 0 or 1 forwards an input at compile
// time (no work, no memory).
#include <kestrel/Kestrel.h>

class MixPass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit MixPass(const kestrel::ParamValues& p);
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    float weight_;
};
