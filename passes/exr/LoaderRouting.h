#pragma once
// The loader's channel routing: which file channel is decoded into which plane (an output's, or
// a scratch plane feeding sums and products), with which fill and which absurd-value fix, and
// which outputs are computed how. It depends only on the plan and on which outputs are consumed,
// so the loader builds it once per run (the first frame) instead of on every frame; each frame
// only looks the planes up (Routing::Slot).
#include <atomic>
#include <cstddef>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "ChannelPlan.h"

namespace kestrel::exr {

using Planes = std::map<ChannelRef, float*>;

/// A direct output channel that a sum, the rest or a derived output reads raw: its absurd
/// values are replaced after them, in [b, e) of its plane, counted (the channel's own plane;
/// a copy of it in a second output is not counted again).
struct Deferred {
    float* plane;
    float fill, lowest;
    std::atomic<size_t>* replaced;  // null: a copy
    bool afterDerived;              // a derived output reads it: after those, in a pass
    void replace(size_t b, size_t e) const;
};

struct Routing {
    /// A plane: channel `channel` of recipe `recipe`'s output, or scratch plane `scratch`.
    struct Slot {
        int recipe = -1, channel = 0, scratch = -1;
    };
    /// As Deferred, with its plane as a slot.
    struct DeferredSlot {
        ChannelRef ref;
        Slot plane;
        float fill, lowest;
        bool counted, afterDerived;
    };

    std::vector<bool> consumed;  ///< per recipe: the outputs this routing was built for
    /// Consumed outputs the plan marks absent (only in unit tests: the engine never binds
    /// one): filled with their fill value.
    std::vector<const Recipe*> absent;
    std::vector<const Recipe*> active;     ///< consumed and present, in plan order
    std::vector<const Recipe*> composite;  ///< sums of products (and caps, rests)
    std::vector<const Recipe*> derived;    ///< computed from channels read to scratch
    /// Where each file channel goes: straight into an output plane when the output is that
    /// channel alone, else into a scratch plane feeding sums and products.
    std::vector<std::pair<ChannelRef, Slot>> dest;  // in ChannelRef order
    size_t scratchPlanes = 0;
    std::map<ChannelRef, float> fills;
    std::vector<std::pair<Slot, ChannelRef>> copies;  ///< a channel wanted in two output planes
    /// Specular's rest from the colour, diffuse and emission planes (addPositiveRest), or null.
    const Recipe* fastRest = nullptr;
    bool emissionBound = false;
    /// Direct channels replaced as decoded -> the lowest valid value (their output's).
    std::map<ChannelRef, float> decodeFix;
    /// Direct channels (-> lowest valid value): the decoder's counts of replaced values.
    std::map<ChannelRef, float> direct;
    std::vector<DeferredSlot> deferred;
    /// The channels of each file role, in ChannelRef order.
    std::map<std::string, std::vector<ChannelRef>> byFile;
    std::vector<std::string> channelsRead;  ///< ChannelRef::str() of every channel decoded
};

/// The routing of `plan` when the outputs `consumed` (per recipe) are.
Routing buildRouting(const Plan& plan, const std::vector<bool>& consumed);

}  // namespace kestrel::exr
