#include "ToneMapPass.h"

#include <algorithm>
#include <cmath>

namespace kestrel::passes {

namespace {
// Above this a value is white under every operator; clamping first keeps the rational
// operators free of Inf/Inf.
constexpr float kMaxLinear = 1e6f;
}  // namespace

float toneMapValue(float x, ToneOperator op) {
    if (!(x > 0.f)) return 0.f;  // negative, zero and NaN
    x = std::min(x, kMaxLinear);
    switch (op) {
        case ToneOperator::Reinhard:
            // Reinhard et al. 2002, eq. 3, per channel.
            return x / (1.f + x);
        case ToneOperator::Aces: {
            // Narkowicz 2015, "ACES Filmic Tone Mapping Curve" (fit of the ACES RRT+ODT).
            float v = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
            return std::clamp(v, 0.f, 1.f);
        }
        case ToneOperator::Clamp:
            return std::min(x, 1.f);
    }
    return 0.f;
}

float srgbEncode(float x) {
    x = std::clamp(x, 0.f, 1.f);
    return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.f / 2.4f) - 0.055f;
}

ToneMapPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "ToneMap", "Linear HDR colour to display [0,1]: exposure, tone curve, sRGB encoding") {
    color = input("color", Format::Float3, "linear HDR colour");
    colorOut = output("color", Format::Float3, "tone-mapped colour in [0,1]");
    param("exposure", &Params::exposure, -30.0, 30.0,
          "exposure in stops: colour is scaled by 2^exposure");
    param("operator", &Params::op, {"reinhard", "aces", "clamp"},
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
                    float v = toneMapValue(src[x] * scale_, p_.op);
                    dst[x] = p_.srgb ? srgbEncode(v) : v;
                }
            }
    });
}

}  // namespace kestrel::passes
