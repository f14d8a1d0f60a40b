// One A-Trous iteration: its declaration, how it adapts to the scene, and which instances run
// fused; the filter itself is ATrousKernels.cpp's (fast) or ATrousReference.h's (exact).
#include "ATrousPass.h"

#include <cstdio>

#include "ATrousKernels.h"
#include "ATrousReference.h"

using namespace kestrel;

ATrousPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "ATrous",
          "One edge-avoiding A-Trous iteration (SVGF eq. 1-5): 5x5 B-spline taps at multiples"
          " of `step`, weighted by depth, normal, object id and variance-normalised luminance;"
          " variance propagated as sum(w^2 Var) / (sum w)^2.") {
    color = input("color", Format::Float3, "illumination to filter");
    variance = optionalInput("variance", Format::Float,
                             "luminance variance; without it the luminance weight uses sigmaColor");
    depth = input("depth", Format::Float, "linear view depth");
    normal = input("normal", Format::Float3, "world-space unit normal");
    objectId =
        optionalInput("objectId", Format::Int32, "object id: taps on another object get weight 0");
    colorOut = output("color", Format::Float3, "filtered illumination");
    varianceOut =
        output("variance", Format::Float, "propagated variance (absent without variance input)");
    fuseOn({&depth, &normal, &objectId}, PassDesc::FusedOutputs::MayDiffer);
    param("step", &Params::step, 1, 1024, "tap spacing in pixels (2^iteration)");
    paramDecimal("sigmaZ", &Params::sigmaZ, 0.0, 1e6,
                 "depth weight: tolerance in units of the depth slope");
    paramDecimal("sigmaN", &Params::sigmaN, 0.0, 1e4,
                 "normal weight exponent on max(0, n_p . n_q)");
    paramDecimal("sigmaL", &Params::sigmaL, 0.0, 1e6,
                 "luminance weight: tolerance in standard deviations");
    paramDecimal("sigmaColor", &Params::sigmaColor, 1e-6, 1e6,
                 "luminance tolerance (absolute) used when no variance is bound");
    param("iteration", &Params::iteration, 0, 1024,
          "this pass's index in its chain (0 first); with iterations, lets one "
          "parameter set how many of a chain's passes run");
    param("iterations", &Params::iterations, 1, 1024,
          "how many iterations the chain runs (a group parameter): a pass with "
          "iteration >= iterations passes color and variance through and is left out");
    param("exact", &Params::exact,
          "run the plain scalar path (libm exp/pow, no SIMD) to measure what the fast"
          " path's approximations cost in error; several times slower");
}

const ATrousPass::Declaration& ATrousPass::declaration() {
    static const Declaration d;
    return d;
}

ATrousBindings::ATrousBindings(PassIO& io) : ATrousBindings(io, ATrousPass::declaration()) {}

ATrousBindings::ATrousBindings(PassIO& io, const ATrousPass::Declaration& d)
    : color(io.input(d.color)),
      depth(io.input(d.depth)),
      normal(io.input(d.normal)),
      var(io.has(d.variance) ? &io.input(d.variance) : nullptr),
      idView(io.has(d.objectId) ? &io.input(d.objectId) : nullptr),
      ids(idView ? idView->ints() : nullptr),
      outColor(io.output(d.colorOut)),
      outVar(var && io.has(d.varianceOut) ? &io.output(d.varianceOut) : nullptr) {}

ATrousPass::ATrousPass(const ParamValues& p) : s_{declaration().read(p)} {
    skipped_ = s_.iteration >= s_.iterations;
}

void ATrousPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    s_.depthPrecision = depthPrecision(rc);
    if (skipped_) {  // beyond the chain's iteration count: an identity, left out by the compiler
        rc.forward(d.colorOut, d.color);
        if (rc.isBound(d.variance)) rc.forward(d.varianceOut, d.variance);
    }
    varianceBound_ = rc.isBound(d.variance);
    if (!varianceBound_) {
        rc.setAbsent(d.varianceOut, "no variance input");
        rc.note("no variance input: luminance weight uses the fixed sigmaColor");
    }
}

std::string ATrousPass::fusionKey() const {
    if (s_.exact || skipped_) return {};
    // Everything the shared geometric work depends on; sigmaL and sigmaColor are per signal.
    // A pair filters both signals with or both without a variance.
    char key[128];
    std::snprintf(key, sizeof key, "step=%d sigmaZ=%a sigmaN=%a depthPrecision=%a variance=%d",
                  s_.step, double(s_.sigmaZ), double(s_.sigmaN), double(s_.depthPrecision),
                  int(varianceBound_));
    return key;
}

namespace {
/// Whether two passes' bindings can be filtered as one pair: the same geometry images and both
/// with or both without a variance input (the kernel's variants are per pair). Their variance
/// outputs may differ: the pair then filters both variances and stores the one that is bound
/// (the specular chain's last iteration, whose variance nobody reads, pairs with the diffuse
/// chain's third).
bool pairable(const ATrousBindings& a, const ATrousBindings& b) {
    return a.depth.planes == b.depth.planes && a.normal.planes == b.normal.planes &&
           a.ids == b.ids && (a.var == nullptr) == (b.var == nullptr);
}
}  // namespace

void ATrousPass::executeFused(FrameContext& ctx, std::span<Pass* const> passes,
                              std::span<PassIO* const> ios) {
    // Pairs share each tap's depth, normal and object-id work (NRD filters diffuse and
    // specular together the same way); an odd one out runs alone.
    size_t i = 0;
    for (; i + 1 < ios.size(); i += 2) {
        const ATrousBindings b0(*ios[i]), b1(*ios[i + 1]);
        if (!pairable(b0, b1)) {
            passes[i]->execute(ctx, *ios[i]);
            passes[i + 1]->execute(ctx, *ios[i + 1]);
            continue;
        }
        const ATrousBindings* b[2] = {&b0, &b1};
        const Settings settings[2] = {static_cast<const ATrousPass&>(*passes[i]).s_,
                                      static_cast<const ATrousPass&>(*passes[i + 1]).s_};
        atrousFilterFast(ctx, b, 2, settings, ios[i]->idlePlanes());
    }
    if (i < ios.size()) passes[i]->execute(ctx, *ios[i]);
}

void ATrousPass::execute(FrameContext& ctx, PassIO& io) {
    if (!s_.exact) {
        const ATrousBindings b0(io);
        const ATrousBindings* b[1] = {&b0};
        atrousFilterFast(ctx, b, 1, &s_, io.idlePlanes());
        return;
    }
    const ATrousBindings b(io);
    const reference::ATrousInputs in{&b.color,  b.var,         &b.depth,         &b.normal,
                                     b.idView,  s_.step,       s_.sigmaZ,        s_.sigmaN,
                                     s_.sigmaL, s_.sigmaColor, s_.depthPrecision};
    ctx.parallelRows(ctx.extent.height,
                     [&](int y0, int y1) { reference::atrous(in, b.outColor, b.outVar, y0, y1); });
}
