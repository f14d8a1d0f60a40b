// The loader's frame: the routed channels decoded into their planes, then the composites, the
// derived outputs and the convention fixes (each in a file of its own: Loader*.cpp).
#include "ExrLoader.h"

#include <algorithm>
#include <filesystem>

#include "LoaderConventions.h"
#include "LoaderDecode.h"

namespace kestrel::exr {

namespace fs = std::filesystem;

const Routing& ExrLoader::routingFor(const PassIO& io) {
    const Declaration& d = declaration();
    std::vector<bool> consumed(d.outputs.size());
    for (size_t k = 0; k < consumed.size(); ++k) consumed[k] = io.has(d.outputs[k]);
    if (!routing_ || routing_->consumed != consumed) {
        routing_ = std::make_unique<Routing>(buildRouting(plan_, consumed));
        planes_.clear();
        for (const auto& [ref, slot] : routing_->dest) planes_[ref] = nullptr;
    }
    return *routing_;
}

float* ExrLoader::plane(PassIO& io, const Routing::Slot& s) const {
    if (s.scratch >= 0) return scratch_[size_t(s.scratch)].get();
    return asFloats(io.output(declaration().outputs[size_t(s.recipe)]), s.channel);
}

void ExrLoader::bindPlanes(PassIO& io, const Routing& rt, size_t N) {
    for (const Recipe* r : rt.absent) {  // only in unit tests: the engine never binds one
        const ImageView& out = output(io, r);
        for (int c = 0; c < std::max(1, out.channels()); ++c)
            fillPlane(asFloats(out, c), N, r->fill);
        if (r->format == Format::Int32) floatsToIds(asFloats(out, 0), N, IdRule::Round);
    }
    if (scratchPixels_ != N || scratch_.size() < rt.scratchPlanes) {
        if (scratchPixels_ != N) scratch_.clear();
        while (scratch_.size() < rt.scratchPlanes) scratch_.push_back(allocatePlane(N));
        scratchPixels_ = N;
    }
    auto p = planes_.begin();  // the same keys, in the same order
    for (const auto& [ref, slot] : rt.dest) (p++)->second = plane(io, slot);
}

size_t ExrLoader::decode(FrameContext& ctx, PassIO& io, const Routing& rt,
                         std::map<ChannelRef, std::atomic<size_t>>& replaced) {
    const int W = int(display_.width()), H = int(display_.height());
    const size_t N = size_t(W) * size_t(H);
    channelsRead_ = rt.channelsRead;
    bool adopted = ready_ != nullptr;
    for (const auto& [ref, slot] : rt.dest) adopted = adopted && ready_->planes.count(ref);
    size_t fileBytes = 0;
    for (const auto& [role, refs] : rt.byFile) {
        ExrInput& in = openRole(role, frame_);
        std::error_code ec;
        fileBytes += size_t(fs::file_size(in.path(), ec));
        if (adopted) {
            for (const ChannelRef& ref : refs) {
                if (rt.decodeFix.count(ref)) replaced[ref] = ready_->replaced[ref].load();
                const float* src = ready_->planes[ref].get();
                float* dst = planes_.at(ref);
                ctx.parallelRows(H, [&](int y0, int y1) {
                    std::copy(src + size_t(y0) * size_t(W), src + size_t(y1) * size_t(W),
                              dst + size_t(y0) * size_t(W));
                });
            }
            continue;
        }
        std::vector<std::pair<std::string, float*>> chans;
        std::vector<float> fillv;
        std::vector<AbsurdFix> fixes;
        for (const ChannelRef& ref : refs) {
            chans.emplace_back(ref.name, planes_.at(ref));
            const float fill = rt.fills.at(ref);
            fillv.push_back(fill);
            const auto d = rt.decodeFix.find(ref);
            const bool fix = d != rt.decodeFix.end();
            fixes.push_back(
                {fix, fill, fix ? &replaced[ref] : nullptr, fix ? d->second : -kAbsurd});
        }
        try {
            // The chunk buffers in planes the graph's memory plan leaves idle while the loader
            // runs, rather than in memory of their own on top of the plan's (docs/benchmarks.md).
            const Workspace lent{io.idlePlanes(), ctx.extent.pixels() * sizeof(float)};
            readChannels(in, display_, W, N, chans, fillv,
                         ctx.parallel ? ctx.parallel->threadCount() : 1, lent, fixes);
        } catch (const std::exception& e) {
            throw FrameError("frame " + std::to_string(frame_) + ": " + in.path() +
                             ": cannot read pixels (corrupt or truncated): " + e.what());
        }
    }
    if (ready_) {
        spare_ = std::move(ready_->planes);
        ready_.reset();
    }
    for (const auto& [slot, ref] : rt.copies) {
        const float* src = planes_.at(ref);
        std::copy(src, src + N, plane(io, slot));
    }
    return fileBytes;
}

void ExrLoader::execute(FrameContext& ctx, PassIO& io) {
    const int W = int(display_.width()), H = int(display_.height());
    const size_t N = size_t(W) * size_t(H);
    const Routing& rt = routingFor(io);
    bindPlanes(io, rt, N);

    // Decode, file by file (LoaderRouting.h says which channel is fixed when).
    std::map<ChannelRef, std::atomic<size_t>> replaced;
    for (const auto& [ref, lowest] : rt.direct)
        replaced[ref];  // no insertion while decoding threads add
    const size_t fileBytes = decode(ctx, io, rt, replaced);
    std::vector<Deferred> deferred;
    for (const Routing::DeferredSlot& d : rt.deferred)
        deferred.push_back({plane(io, d.plane), d.fill, d.lowest,
                            d.counted ? &replaced.at(d.ref) : nullptr, d.afterDerived});

    // Sums of products (Blender light passes times their colour passes), block by block.
    std::vector<std::array<std::atomic<size_t>, 4>> compositeReplaced(rt.composite.size());
    computeComposites(ctx, io, rt, deferred, compositeReplaced);
    computeDerived(ctx, io, rt, W, H);
    // The depth a derived output was computed from: a pass of its own (renders without a
    // position or normal pass only).
    for (const Deferred& d : deferred)
        if (d.afterDerived)
            ctx.parallelRows(H, [&](int y0, int y1) {
                d.replace(size_t(y0) * size_t(W), size_t(y1) * size_t(W));
            });

    // Before the conventions (ids still floats): nothing non-finite or absurd leaves the loader.
    warnReplaced(replacedByOutput(ctx, io, rt, compositeReplaced, replaced, W, H));
    applyConventions(ctx, io, rt, N);

    if (!logged_) logChannels(N, fileBytes);
    if (p_.prefetch) startPrefetch(frame_ + step_, rt.fills, rt.decodeFix);
}

void ExrLoader::logChannels(size_t N, size_t fileBytes) {
    std::string list;
    for (const auto& c : channelsRead_) list += (list.empty() ? "" : ", ") + c;
    // The count at the default level, the names with -v (38 names were ~900 characters).
    spdlog::info(
        "ExrLoader: reading {} channels per frame ({:.2f} MB decoded from {:.2f} MB of files)",
        channelsRead_.size(), double(channelsRead_.size() * N * 4) / 1e6, double(fileBytes) / 1e6);
    spdlog::debug("ExrLoader: channels read: {}", list);
    logged_ = true;
}

}  // namespace kestrel::exr
