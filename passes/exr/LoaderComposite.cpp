// The loader's composites: outputs that are sums of products of file channels (Blender's light
// passes times their colour passes), capped, and the split's rest (Recipe::Rest), computed
// block by block while the block's planes are in cache.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "ExrLoader.h"
#include "LoaderDecode.h"

namespace kestrel::exr {

namespace {

/// out[i - b] += sign * the product of the term's factors (channel c of each), i in [b, e).
void addTerm(const Term& t, const Planes& dest, int c, float sign, float* __restrict out, size_t b,
             size_t e) {
    const float* __restrict f0 = dest.at(t[0][size_t(c)]) + b;
    const size_t n = e - b;
    if (t.size() == 1) {
        for (size_t i = 0; i < n; ++i) out[i] += sign * f0[i];
        return;
    }
    const float* __restrict f1 = dest.at(t[1][size_t(c)]) + b;
    if (t.size() == 2) {
        for (size_t i = 0; i < n; ++i) out[i] += sign * (f0[i] * f1[i]);
        return;
    }
    for (size_t i = 0; i < n; ++i) {
        float v = f0[i] * f1[i];
        for (size_t k = 2; k < t.size(); ++k) v *= dest.at(t[k][size_t(c)])[b + i];
        out[i] += sign * v;
    }
}

/// Pixels per block of the composites: every plane a block reads stays in the core's cache
/// from one recipe to the next (a 1080p Blender frame's ~30 planes: 1 MB per block), and each
/// term looks its planes up once per block.
constexpr size_t kCompositeBlock = 8192;
using Block = std::array<float, kCompositeBlock>;

/// out[i - b] = min(out[i - b], the sum of `cap`) (Recipe::cap), e - b <= kCompositeBlock.
void applyCap(const std::vector<Term>& cap, const Planes& dest, int c, float* out, size_t b,
              size_t e) {
    Block v;
    std::fill(v.begin(), v.begin() + (e - b), 0.f);
    for (const Term& t : cap) addTerm(t, dest, c, 1.f, v.data(), b, e);
    for (size_t i = 0; i < e - b; ++i) out[i] = std::min(out[i], v[i]);
}

/// The emission the split leaves unfiltered: at most the light the split passes leave, t =
/// color - diffuse - specular (an anti-aliased edge against a transparent film's sky has Env
/// but less Combined), so diffuse + specular + emission never exceeds color. t NaN or Inf (a
/// broken pass): the emission as it is.
inline float splitEmission(float e, float t) {
    return t < 0.f ? 0.f : (t < e ? t : e);
}

/// Light in `x` only where finite and positive (a NaN or Inf pass adds none).
inline float finitePositive(float x) {
    return x > 0.f && x <= std::numeric_limits<float>::max() ? x : 0.f;
}

/// Specular plus the positive part of the rest, from planes computed already (color, diffuse,
/// and emission, which is tightened in place by splitEmission; null: none): out = specular +
/// color - diffuse - specular - emission where that is positive. The same values as addRest's.
void addPositiveRest(const float* __restrict color, const float* __restrict diffuse,
                     float* __restrict emission, float* __restrict out, size_t n) {
    for (size_t i = 0; i < n; ++i) {
        const float t = color[i] - diffuse[i] - out[i];
        const float e = emission ? splitEmission(emission[i], t) : 0.f;
        if (emission) emission[i] = e;
        out[i] += finitePositive(t - e);
    }
}

/// out[i - b] += the part of the rest (Recipe::Rest) that `rest` names, e - b <=
/// kCompositeBlock: Positive, t - splitEmission(emission, t) where positive (t = color -
/// passes); Whole, t - min(emission, color), so emission + it = t. `withEmission` false: the
/// graph adds no emission back, so none is taken out.
void addRest(const Recipe::Rest& rest, const Planes& dest, int c, bool withEmission, float* out,
             size_t b, size_t e) {
    Block t, emission;
    const size_t n = e - b;
    for (Block* x : {&t, &emission}) std::fill(x->begin(), x->begin() + n, 0.f);
    for (const Term& term : rest.color) addTerm(term, dest, c, 1.f, t.data(), b, e);
    Block color = t;
    for (const Term& term : rest.passes) addTerm(term, dest, c, -1.f, t.data(), b, e);
    if (withEmission)
        for (const Term& term : rest.emission) addTerm(term, dest, c, 1.f, emission.data(), b, e);
    if (rest.part == Recipe::Rest::Part::Positive) {
        for (size_t i = 0; i < n; ++i)
            out[i] += finitePositive(t[i] - splitEmission(emission[i], t[i]));
        return;
    }
    // Without emission terms (a split without Emit/Env) none is taken: min(0, color) would take
    // a negative colour (a pixel filter's negative lobe) out twice.
    const bool anyEmission = withEmission && !rest.emission.empty();
    for (size_t i = 0; i < n; ++i) {
        const float r = t[i] - (anyEmission ? std::min(emission[i], color[i]) : 0.f);
        out[i] += std::isfinite(r) ? r : 0.f;
    }
}

}  // namespace

void ExrLoader::computeComposites(
    FrameContext& ctx, PassIO& io, const Routing& rt, const std::vector<Deferred>& deferred,
    std::vector<std::array<std::atomic<size_t>, 4>>& compositeReplaced) {
    const Declaration& d = declaration();
    const int W = int(display_.width()), H = int(display_.height());
    const Planes& dest = planes_;
    const auto& composite = rt.composite;
    // Block by block; then the block's absurd values replaced, in the sums and the channels
    // they read (Deferred), while it is in cache.
    ctx.parallelRows(H, [&](int y0, int y1) {
        const size_t end = size_t(y1) * size_t(W);
        for (size_t b = size_t(y0) * size_t(W); b < end; b += kCompositeBlock) {
            const size_t e = std::min(end, b + kCompositeBlock);
            for (size_t k = 0; k < composite.size(); ++k) {
                const Recipe* r = composite[k];
                const ImageView& out = output(io, r);
                const int C = r->format == Format::Int32 ? 1 : channelCount(r->format);
                for (int c = 0; c < C; ++c) {
                    float* o = asFloats(out, c) + b;
                    std::fill(o, o + (e - b), 0.f);
                    for (const Term& t : r->terms) addTerm(t, dest, c, 1.f, o, b, e);
                    if (!r->cap.empty()) applyCap(r->cap, dest, c, o, b, e);
                    if (r == rt.fastRest)
                        addPositiveRest(
                            asFloats(io.output(d.color), c) + b,
                            asFloats(io.output(d.diffuse), c) + b,
                            rt.emissionBound ? asFloats(io.output(d.emission), c) + b : nullptr, o,
                            e - b);
                    else if (r->rest)
                        addRest(*r->rest, dest, c, rt.emissionBound || r->output == "emission", o,
                                b, e);
                }
            }
            for (size_t k = 0; k < composite.size(); ++k) {
                const Recipe* r = composite[k];
                const int C = r->format == Format::Int32 ? 1 : channelCount(r->format);
                for (int c = 0; c < C; ++c)
                    if (const size_t n = replaceAbsurd(asFloats(output(io, r), c) + b, e - b,
                                                       r->fill, r->lowest))
                        compositeReplaced[k][size_t(c)] += n;
            }
            for (const Deferred& x : deferred)
                if (!x.afterDerived) x.replace(b, e);
        }
    });
}

}  // namespace kestrel::exr
