// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one):
// the scalar loops auto-vectorise for each instruction set (and std::fma becomes one
// instruction where there is FMA); the HWY_ONCE part at the end picks the running CPU's
// best target.
#include "ModulatePass.h"

#include <kestrel/PixelMath.h>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "ModulatePass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

// One channel of one row: illumination * albedo + emission + base, sanitised; products and
// sums rounded one by one (no fused multiply-add: the plugin is built with
// -ffp-contract=off). A, E, B: albedo, emission, base fed (compile-time, so the loop is
// branch-free and vectorises).
template <bool A, bool E, bool B>
void modulateRow(int w, const float* src, const float* __restrict a, const float* __restrict e,
                 const float* __restrict b, float* dst, float floor) {
    // dst may be src (in place): each pixel is read before it is written, so no iteration
    // depends on another.
#pragma GCC ivdep
    for (int x = 0; x < w; ++x) {
        float v = px::sanitize(src[x]);
        if constexpr (A) v *= px::demodulationAlbedo(a[x], floor);
        if constexpr (E) v += px::sanitize(e[x]);
        if constexpr (B) v += px::sanitize(b[x]);
        dst[x] = px::sanitize(v);
    }
}

using RowFn = void (*)(int, const float*, const float*, const float*, const float*, float*, float);

template <bool A, bool E>
RowFn pick(bool b) {
    return b ? modulateRow<A, E, true> : modulateRow<A, E, false>;
}

/// The pass for this target (its parameters as arguments).
void executeOnTarget(FrameContext& ctx, PassIO& io, float albedoFloor_) {
    const ModulatePass::Declaration& d = ModulatePass::declaration();
    const ImageView& illum = io.input(d.illumination);
    const ImageView* albedo = io.has(d.albedo) ? &io.input(d.albedo) : nullptr;
    const ImageView* emission = io.has(d.emission) ? &io.input(d.emission) : nullptr;
    const ImageView* base = io.has(d.base) ? &io.input(d.base) : nullptr;
    const ImageView& out = io.output(d.color);
    const float floor = std::max(albedoFloor_, 1e-8f);  // same divisor as Demodulate
    const int w = ctx.extent.width;
    const RowFn row = albedo ? (emission ? pick<true, true>(base) : pick<true, false>(base))
                             : (emission ? pick<false, true>(base) : pick<false, false>(base));
    ctx.parallelRows(ctx.extent.height, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int c = 0; c < 3; ++c)
                row(w, illum.row(c, y), albedo ? albedo->row(c, y) : nullptr,
                    emission ? emission->row(c, y) : nullptr, base ? base->row(c, y) : nullptr,
                    out.row(c, y), floor);
    });
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel {
namespace {
HWY_EXPORT(executeOnTarget);
}  // namespace
}  // namespace kestrel

using namespace kestrel;

ModulatePass::Declaration::Declaration()
    : kestrel::Declaration<Params>("Modulate",
                                   "Re-applies albedo and emission: color = illumination * albedo "
                                   "(1 below albedoFloor, as Demodulate) + emission + base. "
                                   "Identity when nothing optional is bound.") {
    illumination = input("illumination", Format::Float3, "filtered demodulated illumination");
    albedo = optionalInput("albedo", Format::Float3, "surface albedo to multiply back");
    emission = optionalInput("emission", Format::Float3, "emitted radiance to add back");
    base = optionalInput("base", Format::Float3, "radiance added on top (sums split components)");
    color = output("color", Format::Float3, "radiance", &illumination);
    paramDecimal("albedoFloor", &Params::albedoFloor, 0.0, 1.0,
                 "lower bound of the albedo factor (must match Demodulate's)");
}

const ModulatePass::Declaration& ModulatePass::declaration() {
    static const Declaration d;
    return d;
}

void ModulatePass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (!rc.isBound(d.albedo) && !rc.isBound(d.emission) && !rc.isBound(d.base)) {
        rc.forward(d.color, d.illumination);
        rc.note("no albedo, emission or base bound: color is the illumination itself");
    }
}

void ModulatePass::execute(FrameContext& ctx, PassIO& io) {
    HWY_DYNAMIC_DISPATCH(executeOnTarget)(ctx, io, p_.albedoFloor);
}
#endif  // HWY_ONCE
