#include "MixPass.h"

#include <kestrel/PixelMath.h>

using namespace kestrel;

MixPass::Declaration::Declaration()
    : kestrel::Declaration<Params>("Mix",
                                   "Linear blend of two colours: color = a + weight * (b - a).") {
    a = input("a", Format::Float3, "the colour at weight 0");
    b = input("b", Format::Float3, "the colour at weight 1");
    // pointwise: reads a pixel of a before writing it
    color = output("color", Format::Float3, "the blend", &a);
    param("weight", &Params::weight, 0.0, 1.0,
          "share of b; 0 and 1 forward an input unchanged (otherwise non-finite input values "
          "count as 0)");
}

const MixPass::Declaration& MixPass::declaration() {
    static const Declaration d;
    return d;
}

void MixPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (p_.weight == 0.f) {
        rc.forward(d.color, d.a);
        rc.note("weight 0: color is a");
    } else if (p_.weight == 1.f) {
        rc.forward(d.color, d.b);
        rc.note("weight 1: color is b");
    }
}

void MixPass::execute(FrameContext& ctx, PassIO& io) {
    const Declaration& d = declaration();
    const ImageView &a = io.input(d.a), &b = io.input(d.b), &out = io.output(d.color);
    const int w = ctx.extent.width;
    const float t = p_.weight;
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
