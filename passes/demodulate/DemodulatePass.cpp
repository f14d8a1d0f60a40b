// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one):
// the scalar loops auto-vectorise for each instruction set (and std::fma becomes one
// instruction where there is FMA); the HWY_ONCE part at the end picks the running CPU's
// best target.
#include "DemodulatePass.h"

#include <kestrel/PixelMath.h>

#include <algorithm>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "DemodulatePass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

// One channel of one row: (colour - emission) / albedo, sanitised, and the albedo Modulate
// multiplies back by (px::modulationAlbedo) into aOut when it is not null. A, E: albedo,
// emission fed (compile-time, so the loop is branch-free and vectorises).
template <bool A, bool E>
void demodulateRow(int w, const float* src, const float* a, const float* __restrict e, float* dst,
                   float* aOut, float floor, bool guard) {
    // dst may be src and aOut may be a (in place): each pixel is read before it is written, so
    // no iteration depends on another.
#pragma GCC ivdep
    for (int x = 0; x < w; ++x) {
        float v = px::sanitize(src[x]);
        if constexpr (E) v -= px::sanitize(e[x]);
        if constexpr (A) {
            const bool divided = a[x] >= floor && a[x] <= 1e30f;  // as demodulationAlbedo
            const float m =
                guard ? px::modulationAlbedo(a[x], v, floor) : px::demodulationAlbedo(a[x], floor);
            // Below the floor the light goes through undivided; a pixel without light has none.
            v = divided ? v / m : (guard ? std::max(v, 0.f) : v);
            if (aOut) aOut[x] = m;
        }
        dst[x] = px::sanitize(v);
    }
}

/// The pass for this target (its parameters as arguments).
void executeOnTarget(FrameContext& ctx, PassIO& io, float albedoFloor_) {
    const DemodulatePass::Declaration& d = DemodulatePass::declaration();
    const ImageView& color = io.input(d.color);
    const ImageView* albedo = io.has(d.albedo) ? &io.input(d.albedo) : nullptr;
    const ImageView* emission = io.has(d.emission) ? &io.input(d.emission) : nullptr;
    const ImageView& out = io.output(d.illumination);
    const ImageView* albedoOut = albedo && io.has(d.albedoOut) ? &io.output(d.albedoOut) : nullptr;
    // With object ids the filters keep an emitter apart from the lit objects around it: the
    // albedo Modulate multiplies by is demodulationAlbedo's (see the albedo output).
    const bool guard = !io.has(d.objectId);
    // A zero floor would divide by zero on black albedo: keep the divisor a normal float.
    const float floor = std::max(albedoFloor_, 1e-8f);
    const int w = ctx.extent.width;
    auto row = albedo ? (emission ? demodulateRow<true, true> : demodulateRow<true, false>)
                      : (emission ? demodulateRow<false, true> : demodulateRow<false, false>);
    ctx.parallelRows(ctx.extent.height, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int c = 0; c < 3; ++c)
                row(w, color.row(c, y), albedo ? albedo->row(c, y) : nullptr,
                    emission ? emission->row(c, y) : nullptr, out.row(c, y),
                    albedoOut ? albedoOut->row(c, y) : nullptr, floor, guard);
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

DemodulatePass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "Demodulate",
          "Divides the emission-free radiance by the albedo: illumination = (color - emission) / "
          "albedo (channels with albedo below albedoFloor are not demodulated). Identity when "
          "neither albedo nor emission is bound.") {
    color = input("color", Format::Float3, "noisy radiance");
    albedo = optionalInput("albedo", Format::Float3, "surface albedo to divide out");
    emission = optionalInput("emission", Format::Float3, "emitted radiance to subtract first");
    illumination =
        output("illumination", Format::Float3, "demodulated illumination (finite)", &color);
    objectId = optionalInput("objectId", Format::Int32,
                             "object ids, when the render has them (not read: with them the "
                             "filters keep an emitter apart from the lit objects around it)");
    albedoOut = output(
        "albedo", Format::Float3,
        "the albedo to multiply back by (Modulate's albedo): the input albedo, 1 below "
        "albedoFloor (not demodulated). Without object ids, below the floor it is 1 only where "
        "the pixel has light of its own in this colour and the floor where it has none (the "
        "light is then 0), so what the filters spread into a black pixel (an emitter's) from the "
        "lit surface around it comes back scaled by the floor. Absent without an albedo",
        &albedo);
    paramDecimal("albedoFloor", &Params::albedoFloor, 0.0, 1.0,
                 "lower bound of the albedo divisor (dark albedo would amplify noise)");
}

const DemodulatePass::Declaration& DemodulatePass::declaration() {
    static const Declaration d;
    return d;
}

void DemodulatePass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (!rc.isBound(d.albedo)) rc.setAbsent(d.albedoOut, "no albedo is bound");
    if (!rc.isBound(d.albedo) && !rc.isBound(d.emission)) {
        rc.forward(d.illumination, d.color);
        rc.note("no albedo and no emission bound: illumination is the colour itself");
    }
}

void DemodulatePass::execute(FrameContext& ctx, PassIO& io) {
    HWY_DYNAMIC_DISPATCH(executeOnTarget)(ctx, io, p_.albedoFloor);
}
#endif  // HWY_ONCE
