#include "BackgroundEmissionPass.h"

#include <kestrel/PixelMath.h>

#include <cstdint>
#include <vector>

using namespace kestrel;

BackgroundEmissionPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "BackgroundEmission",
          "Joins the background to the emission: emission = color where the depth is the "
          "background (no surface: the environment seen directly, exact at 1 spp), else the "
          "emission input (0 when not fed). Feeds a chain that subtracts its emission before "
          "filtering and adds it back after, so the background comes out as it went in.") {
    color = input("color", Format::Float3, "the frame's colour");
    depth =
        input("depth", Format::Float, "linear depth; the background at or beyond 1e10 (or NaN)");
    emission = optionalInput("emission", Format::Float3, "the render's own emission, if any");
    // pointwise: reads a pixel before writing it
    emissionOut = output("emission", Format::Float3,
                         "the emission with the background joined to it", &emission);
}

const BackgroundEmissionPass::Declaration& BackgroundEmissionPass::declaration() {
    static const Declaration d;
    return d;
}

void BackgroundEmissionPass::execute(FrameContext& ctx, PassIO& io) {
    const Declaration& d = declaration();
    const ImageView &color = io.input(d.color), &depth = io.input(d.depth),
                    &out = io.output(d.emissionOut);
    const ImageView* emission = io.has(d.emission) ? &io.input(d.emission) : nullptr;
    const int w = ctx.extent.width;
    ctx.parallelRows(ctx.extent.height, [&](int y0, int y1) {
        std::vector<uint8_t> background(
            static_cast<size_t>(w));  // one test per pixel, not per channel
        for (int y = y0; y < y1; ++y) {
            const float* z = depth.row(0, y);
            for (int x = 0; x < w; ++x)
                background[size_t(x)] = px::sanitizeDepth(z[x]) >= kBackgroundDepth;
            for (int c = 0; c < 3; ++c) {
                const float *col = color.row(c, y), *e = emission ? emission->row(c, y) : nullptr;
                float* o = out.row(c, y);
                for (int x = 0; x < w; ++x)
                    o[x] = background[size_t(x)] ? px::sanitize(col[x])
                                                 : (e ? px::sanitize(e[x]) : 0.f);
            }
        }
    });
}
