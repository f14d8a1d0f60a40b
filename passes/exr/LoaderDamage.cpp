// The loader's account of damaged input (Absurd.h, docs/errors.md): the values the policy
// replaced this frame, by output channel, in one warning per frame.
#include <algorithm>
#include <array>
#include <atomic>

#include "Absurd.h"
#include "ExrLoader.h"
#include "LoaderDecode.h"

namespace kestrel::exr {

namespace {

/// A computed output (positions, normals from depth): its absurd values replaced by `fill`
/// in a pass of its own (renders without those passes only); how many per channel.
std::array<size_t, 4> replaceAbsurdInPlanes(FrameContext& ctx, const ImageView& out, int W, int H,
                                            float fill) {
    std::array<std::atomic<size_t>, 4> count{};
    ctx.parallelRows(H, [&](int y0, int y1) {
        for (int c = 0; c < std::min(4, out.channels()); ++c)
            if (const size_t n = replaceAbsurd(asFloats(out, c) + size_t(y0) * size_t(W),
                                               size_t(y1 - y0) * size_t(W), fill))
                count[size_t(c)] += n;
    });
    return {count[0].load(), count[1].load(), count[2].load(), count[3].load()};
}

}  // namespace

/// Warns once for the frame, counting by output channel, where the policy replaced values.
void ExrLoader::warnReplaced(const std::vector<std::pair<std::string, size_t>>& replaced) const {
    std::string counts;
    for (const auto& [channel, n] : replaced)
        if (n) counts += fmt::format("{}{} in {}", counts.empty() ? "" : ", ", n, channel);
    // One line per frame: a whole damaged sequence says so on every frame it damages.
    if (!counts.empty())
        spdlog::warn(
            "frame {}: {}: NaN, infinite or absurd (|v| > 1e30, light < -1e8, albedo < 0) input "
            "values "
            "replaced by the output's fill value, as for a missing channel (docs/layouts.md): {}",
            frame_, open_.empty() ? p_.path : open_.front().second->path(), counts);
}

/// The values the policy replaced this frame per output channel ("color.R"), in plan order:
/// decoded channels counted by the decoder (a channel copied to a second output counts there
/// too), sums by their blocks; outputs computed from depth are checked here.
std::vector<std::pair<std::string, size_t>> ExrLoader::replacedByOutput(
    FrameContext& ctx, PassIO& io, const Routing& rt,
    const std::vector<std::array<std::atomic<size_t>, 4>>& compositeReplaced,
    const std::map<ChannelRef, std::atomic<size_t>>& decoded, int W, int H) const {
    const auto& composite = rt.composite;
    std::vector<std::pair<std::string, size_t>> counts;
    for (const Recipe* r : rt.active) {
        if (r->reflectionOf) continue;  // 0 or 1 only
        const ImageView& out = output(io, r);
        std::array<size_t, 4> n{};
        if (r->fromDepth) {
            n = replaceAbsurdInPlanes(ctx, out, W, H, r->fill);
        } else if (r->isDirect()) {
            for (size_t c = 0; c < r->terms[0][0].size() && c < 4; ++c)
                n[c] = decoded.at(r->terms[0][0][c]).load();
        } else {
            const size_t k =
                size_t(std::find(composite.begin(), composite.end(), r) - composite.begin());
            for (size_t c = 0; c < 4; ++c) n[c] = compositeReplaced[k][c].load();
        }
        for (int c = 0; c < std::min(4, std::max(1, out.channels())); ++c)
            counts.emplace_back(r->output + "." + "RGBA"[c], n[size_t(c)]);
    }
    return counts;
}

}  // namespace kestrel::exr
