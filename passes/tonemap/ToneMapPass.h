#pragma once
// ToneMap: linear HDR colour -> display-referred [0,1] colour, for previews and image metrics
// (PSNR/SSIM on tone-mapped values, docs/design.md section 7).
#include <kestrel/Kestrel.h>

#include "display/ToneMap.h"

namespace kestrel::passes {

class ToneMapPass final : public Pass {
public:
    struct Params {
        double exposure = 0.0;  ///< double: the scale 2^exposure is computed in double
        display::ToneCurve op = display::ToneCurve::Aces;
        bool srgb = true;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        InputPort color;
        OutputPort colorOut;
    };
    static const Declaration& declaration();

    static PassDesc describe() { return declaration().desc(); }
    explicit ToneMapPass(const ParamValues& params);
    void execute(FrameContext& ctx, PassIO& io) override;

private:
    Params p_;
    float scale_ = 1.f;  // 2^exposure
};

}  // namespace kestrel::passes
