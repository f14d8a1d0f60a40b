#pragma once
// ToneMap: linear HDR colour -> display-referred [0,1] colour, for previews and image metrics
// (PSNR/SSIM on tone-mapped values, docs/design.md section 7).
#include <kestrel/Kestrel.h>

namespace kestrel::passes {

enum class ToneOperator { Reinhard, Aces, Clamp };

/// Tone-maps one linear value already scaled by the exposure. Never returns NaN; result in [0,1].
float toneMapValue(float x, ToneOperator op);
/// sRGB opto-electronic transfer function (IEC 61966-2-1) of a value in [0,1].
float srgbEncode(float x);

class ToneMapPass final : public Pass {
public:
    struct Params {
        double exposure = 0.0;  ///< double: the scale 2^exposure is computed in double
        ToneOperator op = ToneOperator::Aces;
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
