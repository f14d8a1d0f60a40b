#include "LoaderRouting.h"

#include <algorithm>

#include "Absurd.h"
#include "kestrel/Conventions.h"

namespace kestrel::exr {

void Deferred::replace(size_t b, size_t e) const {
    const size_t n = replaceAbsurd(plane + b, e - b, fill, lowest);
    if (n && replaced) *replaced += n;
}

namespace {

/// The channels that sums, the rest (Recipe::Rest; fastRest: from the colour, diffuse and
/// emission planes) and derived outputs read.
std::set<ChannelRef> channelsReadRaw(const Routing& rt, const Plan& plan) {
    std::set<ChannelRef> raw;
    for (const auto* list : {&rt.composite, &rt.derived})
        for (const Recipe* r : *list)
            for (const auto& c : r->channels()) raw.insert(c);
    if (rt.fastRest)
        for (const char* o : {"color", "diffuse", "emission"})
            if (const Recipe* x = plan.find(o); x && !x->absent && x->isDirect())
                for (const auto& c : x->terms[0][0]) raw.insert(c);
    return raw;
}

/// Sorts the consumed outputs into absent, derived, direct and composite; direct channels get
/// their output's planes (a channel wanted twice is copied), the rest scratch planes.
void routeChannels(const Plan& plan, Routing& rt) {
    std::map<ChannelRef, Routing::Slot> dest;
    for (size_t k = 0; k < plan.recipes.size(); ++k) {
        const Recipe& r = plan.recipes[k];
        if (!rt.consumed[k]) continue;
        if (r.absent) {
            rt.absent.push_back(&r);
            continue;
        }
        rt.active.push_back(&r);
        if (r.fromDepth || r.reflectionOf) {  // computed from channels read to scratch
            rt.derived.push_back(&r);
            continue;
        }
        if (!r.isDirect()) {
            rt.composite.push_back(&r);
            continue;
        }
        const Factor& f = r.terms[0][0];
        for (size_t c = 0; c < f.size(); ++c) {
            const Routing::Slot slot{int(k), int(c), -1};
            if (dest.count(f[c])) {
                rt.copies.emplace_back(slot, f[c]);
            } else {
                dest[f[c]] = slot;
                rt.fills[f[c]] = r.fill;
            }
        }
    }
    std::vector<ChannelRef> scratchRefs;
    for (const Recipe* r : rt.active)
        for (const auto& c : r->channels())
            if (!dest.count(c) &&
                std::find(scratchRefs.begin(), scratchRefs.end(), c) == scratchRefs.end())
                scratchRefs.push_back(c);
    for (size_t i = 0; i < scratchRefs.size(); ++i) {
        const ChannelRef& mask = scratchRefs[i];
        dest[mask] = Routing::Slot{-1, 0, int(i)};
        bool isMask = false;
        for (const Recipe* r : rt.active) isMask |= r->backgroundMask && *r->backgroundMask == mask;
        rt.fills[mask] = isMask ? float(kBackgroundId) : 0.f;
    }
    rt.scratchPlanes = scratchRefs.size();
    rt.dest.assign(dest.begin(), dest.end());
    for (const auto& [ref, slot] : rt.dest) {
        rt.byFile[ref.file].push_back(ref);
        rt.channelsRead.push_back(ref.str());
    }
}

}  // namespace

Routing buildRouting(const Plan& plan, const std::vector<bool>& consumed) {
    Routing rt;
    rt.consumed = consumed;
    routeChannels(plan, rt);
    auto isConsumed = [&](const char* output) {
        const Recipe* r = plan.find(output);
        return rt.consumed[size_t(r - plan.recipes.data())];
    };

    // Specular's rest from the colour, diffuse and emission planes when this frame computes
    // them (they come first in the plan; svgf.json binds all three): three reads per pixel
    // instead of every split term again, and the emission tightened in place.
    const Recipe* spec = plan.find("specular");
    rt.emissionBound = isConsumed("emission") && !plan.find("emission")->absent;
    if (spec->rest && spec->rest->part == Recipe::Rest::Part::Positive && isConsumed("specular") &&
        isConsumed("color") && isConsumed("diffuse") && !plan.find("color")->absent &&
        !plan.find("diffuse")->absent)
        rt.fastRest = spec;

    // A channel decoded straight into its output has its absurd values replaced as it is
    // decoded (Absurd.h), unless a sum, the rest or a derived output reads it: those read it
    // raw (a non-finite pass adds no light to the rest) and it is replaced after them
    // (Deferred). Scratch channels stay raw.
    for (const Recipe* r : rt.active)
        if (r->isDirect() && !r->fromDepth && !r->reflectionOf)
            for (const auto& c : r->terms[0][0]) rt.direct.emplace(c, r->lowest);
    const std::set<ChannelRef> readRaw = channelsReadRaw(rt, plan);
    std::set<ChannelRef> readByDerived;
    for (const Recipe* r : rt.derived)
        for (const auto& c : r->channels()) readByDerived.insert(c);
    for (const auto& [ref, lowest] : rt.direct) {
        if (!readRaw.count(ref)) {
            rt.decodeFix.emplace(ref, lowest);
            continue;
        }
        const bool late = readByDerived.count(ref) > 0;
        // A copy for the lambda: clang before 16 does not capture structured bindings (C++20).
        const ChannelRef key = ref;
        const Routing::Slot own = std::find_if(rt.dest.begin(), rt.dest.end(), [&](const auto& d) {
                                      return d.first == key;
                                  })->second;
        rt.deferred.push_back({ref, own, rt.fills[ref], lowest, true, late});
        for (const auto& [plane, r] : rt.copies)
            if (r == ref) rt.deferred.push_back({ref, plane, rt.fills[ref], lowest, false, late});
    }
    return rt;
}

}  // namespace kestrel::exr
