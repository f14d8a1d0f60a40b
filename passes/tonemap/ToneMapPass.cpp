#include "ToneMapPass.h"

#include <cmath>

namespace kestrel::passes {

ToneMapPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "ToneMap", "Linear HDR colour to display [0,1]: exposure, tone curve, sRGB encoding") {
    color = input("color", Format::Float3, "linear HDR colour");
    colorOut = output("color", Format::Float3, "tone-mapped colour in [0,1]");
    param("exposure", &Params::exposure, -30.0, 30.0,
          "exposure in stops: colour is scaled by 2^exposure");
    param("operator", &Params::op, display::toneCurveNames(),
          "tone curve: reinhard x/(1+x), aces (Narkowicz fit), clamp to [0,1]");
    param("srgb", &Params::srgb, "apply the sRGB transfer function (off: linear [0,1] output)");
}

const ToneMapPass::Declaration& ToneMapPass::declaration() {
    static const Declaration d;
    return d;
}

ToneMapPass::ToneMapPass(const ParamValues& params)
    : p_(declaration().read(params)), scale_(float(std::exp2(p_.exposure))) {}

void ToneMapPass::execute(FrameContext& ctx, PassIO& io) {
    const Declaration& d = declaration();
    const ImageView& in = io.input(d.color);
    const ImageView& out = io.output(d.colorOut);
    const int w = in.width();
    ctx.parallelRows(in.height(), [&](int y0, int y1) {
        for (int c = 0; c < 3; ++c)
            for (int y = y0; y < y1; ++y) {
                const float* src = in.row(c, y);
                float* dst = out.row(c, y);
                for (int x = 0; x < w; ++x) {
                    const float v = display::toneMap(src[x] * scale_, p_.op);
                    dst[x] = p_.srgb ? display::srgbEncode(v) : v;
                }
            }
    });
}

}  // namespace kestrel::passes
