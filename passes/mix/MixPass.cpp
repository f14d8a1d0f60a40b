#include "MixPass.h"

#include <kestrel/PixelMath.h>

using namespace kestrel;

PassDesc MixPass::describe() {
    PassDesc d("Mix", "Linear blend of two colours: color = a + weight * (b - a).");
    d.input("a", Format::Float3, "the colour at weight 0")
        .input("b", Format::Float3, "the colour at weight 1")
        .output("color", Format::Float3, "the blend")
        .inPlaceOf("a")  // pointwise: reads a pixel of a before writing it
        .paramFloat("weight", 0.5, 0.0, 1.0,
                    "share of b; 0 and 1 forward an input unchanged (otherwise non-finite input "
                    "values count as 0)");
    return d;
}

MixPass::MixPass(const ParamValues& p) : weight_(p.getFloat("weight")) {}

void MixPass::resolve(ResolveContext& rc) {
    if (weight_ == 0.f) {
        rc.forward("color", "a");
        rc.note("weight 0: color is a");
    } else if (weight_ == 1.f) {
        rc.forward("color", "b");
        rc.note("weight 1: color is b");
    }
}

void MixPass::execute(FrameContext& ctx, PassIO& io) {
    const ImageView &a = io.input("a"), &b = io.input("b"), &out = io.output("color");
    const int w = ctx.extent.width;
    const float t = weight_;
    ctx.parallelRows(ctx.extent.height, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int c = 0; c < 3; ++c) {
                const float *pa = a.row(c, y), *pb = b.row(c, y);
                float* po = out.row(c, y);
                for (int x = 0; x < w; ++x) {
                    const float va = px::sanitize(pa[x]);
                    po[x] = va + t * (px::sanitize(pb[x]) - va);
                }
            }
    });
}
