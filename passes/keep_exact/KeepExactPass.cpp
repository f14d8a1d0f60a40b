#include "KeepExactPass.h"

#include <kestrel/PixelMath.h>
#include <kestrel/Scratch.h>

#include <algorithm>
#include <cmath>

using namespace kestrel;

KeepExactPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "KeepExact",
          "Keeps the render's 1-spp colour where it is exact (a smooth mirror's view of a light "
          "or the sky, agreeing over its 3x3 window), the filtered colour elsewhere; left out "
          "where the scene has no mask") {
    color = input("color", Format::Float3, "the filtered colour");
    rendered = input("rendered", Format::Float3, "the render's own colour (1 spp, unfiltered)");
    mask = optionalInput("mask", Format::Float,
                         "1 where the path reached a light or the sky through near-specular "
                         "bounces only (ExrLoader's lightThroughMirror)");
    // pointwise on color: each pixel reads only its own filtered value
    colorOut = output("color", Format::Float3, "`rendered` where kept, else `color`", &color);
    param("agreement", &Params::agreement, 1.0, 1e6,
          "largest ratio of the brightest to the darkest 1-spp luminance in a kept pixel's 3x3 "
          "window (1 keeps only windows of one value)");
}

const KeepExactPass::Declaration& KeepExactPass::declaration() {
    static const Declaration d;
    return d;
}

void KeepExactPass::resolve(ResolveContext& rc) {
    // Without a mask the filtered colour everywhere: the pass is left out (the compiler counts
    // it with the absent input that caused it).
    const Declaration& d = declaration();
    if (!rc.isBound(d.mask)) rc.forward(d.colorOut, d.color);
}

namespace {

/// The 1-spp luminance where a pixel may be kept (on the mask, every channel a finite,
/// non-negative radiance, not black), else 0: a window with a 0 in it keeps nothing.
float keepable(const ImageView& rendered, const ImageView& mask, int x, int y) {
    if (!(mask.at(0, x, y) > 0.5f)) return 0.f;
    float v[3];
    for (int c = 0; c < 3; ++c) {
        v[c] = rendered.at(c, x, y);
        if (!(v[c] >= 0.f && v[c] <= px::kMaxRadiance)) return 0.f;  // false for NaN
    }
    return px::luminance(v[0], v[1], v[2]);
}

}  // namespace

void KeepExactPass::execute(FrameContext& ctx, PassIO& io) {
    const Declaration& d = declaration();
    const ImageView &rendered = io.input(d.rendered), &mask = io.input(d.mask),
                    &out = io.output(d.colorOut);
    const ImageView& color = io.input(d.color);
    const int w = ctx.extent.width, h = ctx.extent.height;
    const float agreement = p_.agreement;
    // Each pixel's keepable luminance first: every window reads nine (a plane of scratch).
    const auto lease = ScratchPool::acquire(1, size_t(w) * size_t(h));
    float* lum = lease[0];
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int x = 0; x < w; ++x)
                lum[size_t(y) * size_t(w) + size_t(x)] = keepable(rendered, mask, x, y);
    });
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int x = 0; x < w; ++x) {
                bool keep = x > 0 && y > 0 && x + 1 < w && y + 1 < h;  // a whole window
                float lo = 0.f, hi = 0.f;
                for (int dy = -1; keep && dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const float l = lum[size_t(y + dy) * size_t(w) + size_t(x + dx)];
                        lo = dy == -1 && dx == -1 ? l : std::min(lo, l);
                        hi = std::max(hi, l);
                    }
                keep = keep && lo > 0.f && hi <= agreement * lo;
                for (int c = 0; c < 3; ++c) {
                    const float f = color.at(c, x, y);  // read before the in-place write
                    out.at(c, x, y) = keep ? rendered.at(c, x, y) : f;
                }
            }
    });
}
