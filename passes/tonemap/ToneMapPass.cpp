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

PassDesc ToneMapPass::describe() {
    PassDesc d("ToneMap",
               "Linear HDR colour to display [0,1]: exposure, tone curve, sRGB encoding");
    d.input("color", Format::Float3, "linear HDR colour")
        .output("color", Format::Float3, "tone-mapped colour in [0,1]")
        .paramFloat("exposure", 0.0, -30.0, 30.0,
                    "exposure in stops: colour is scaled by 2^exposure")
        .paramEnum("operator", "aces", {"reinhard", "aces", "clamp"},
                   "tone curve: reinhard x/(1+x), aces (Narkowicz fit), clamp to [0,1]")
        .paramBool("srgb", true, "apply the sRGB transfer function (off: linear [0,1] output)");
    return d;
}

ToneMapPass::ToneMapPass(const ParamValues& params)
    : scale_(float(std::exp2(params.getDouble("exposure")))), srgb_(params.getBool("srgb")) {
    const std::string& op = params.getString("operator");
    op_ = op == "reinhard" ? ToneOperator::Reinhard
          : op == "clamp"  ? ToneOperator::Clamp
                           : ToneOperator::Aces;
}

void ToneMapPass::execute(FrameContext& ctx, PassIO& io) {
    const ImageView& in = io.input("color");
    const ImageView& out = io.output("color");
    const int w = in.width();
    ctx.parallelRows(in.height(), [&](int y0, int y1) {
        for (int c = 0; c < 3; ++c)
            for (int y = y0; y < y1; ++y) {
                const float* src = in.row(c, y);
                float* dst = out.row(c, y);
                for (int x = 0; x < w; ++x) {
                    float v = toneMapValue(src[x] * scale_, op_);
                    dst[x] = srgb_ ? srgbEncode(v) : v;
                }
            }
    });
}

}  // namespace kestrel::passes
