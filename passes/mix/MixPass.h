#pragma once
// Mix: color = a + weight * (b - a), per channel. svgf-chain.json uses it for the colour history:
// between the temporal accumulation (a) and its first A-Trous iteration (b), which SVGF
// (Schied et al. 2017, section 4.3) feeds back whole. Weight 0 or 1 forwards an input at compile
// time (no work, no memory).
#include <kestrel/Kestrel.h>

class MixPass final : public kestrel::Pass {
public:
    struct Params {
        float weight = 0.5f;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort a, b;
        kestrel::OutputPort color;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit MixPass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
};
