// The loader's read-ahead (parameter "prefetch"): the next frame's channels decoded on a
// background thread while the graph computes this one; beginFrame adopts them.
#include <algorithm>

#include "ExrLoader.h"
#include "LoaderDecode.h"

namespace kestrel::exr {

void ExrLoader::joinPrefetch() {
    if (prefetchJob_.valid()) prefetchJob_.get();  // the job catches everything itself
}

void ExrLoader::startPrefetch(int64_t frame, const std::map<ChannelRef, float>& fills,
                              const std::map<ChannelRef, float>& direct) {
    joinPrefetch();  // execute without beginFrame (tests): never two read-aheads at once
    if (pending_) {
        spare_ = std::move(pending_->planes);
        pending_.reset();
    }
    if (frame > lastFrame_ || fills.empty()) return;
    const int W = int(display_.width());
    const size_t N = size_t(W) * size_t(display_.height());
    if (spareN_ != N) spare_.clear();  // planes of another frame size
    spareN_ = N;
    auto job = std::make_unique<Prefetch>();
    job->frame = frame;
    // Files in the order execute opens them: the primary first (its window is the frame's).
    std::string primary = plan_.layout == Layout::Games202 ? "beauty" : "";
    std::vector<std::string> roles{primary};
    std::vector<std::vector<std::pair<std::string, float*>>> chans(1);
    std::vector<std::vector<float>> fillv(1);
    std::vector<std::vector<AbsurdFix>> fixes(1);
    for (const auto& [ref, fill] : fills) {
        auto it = std::find(roles.begin(), roles.end(), ref.file);
        size_t k = size_t(it - roles.begin());
        if (it == roles.end()) {
            roles.push_back(ref.file);
            chans.emplace_back();
            fillv.emplace_back();
            fixes.emplace_back();
        }
        auto sp = spare_.find(ref);
        PlaneStorage plane = sp != spare_.end() ? std::move(sp->second) : allocatePlane(N);
        chans[k].emplace_back(ref.name, plane.get());
        fillv[k].push_back(fill);
        const auto d = direct.find(ref);
        fixes[k].push_back({d != direct.end(), fill, &job->replaced[ref],
                            d != direct.end() ? d->second : -kAbsurd});
        job->planes[ref] = std::move(plane);
    }
    spare_.clear();
    pending_ = std::move(job);
    cancel_ = false;
    Prefetch* P = pending_.get();
    const Box display = display_;
    prefetchJob_ =
        std::async(std::launch::async, [this, P, roles = std::move(roles), chans = std::move(chans),
                                        fillv = std::move(fillv), fixes = std::move(fixes), display,
                                        W, N, threads = threads_] {
            try {
                for (const auto& role : roles) {
                    if (cancel_) return;
                    auto in = std::make_unique<ExrInput>(filePath(role, P->frame), p_.maxPixels);
                    if (in->displayWindow() != display) return;  // read again, unprefetched
                    P->open.emplace_back(role, std::move(in));
                }
                for (size_t k = 0; k < roles.size(); ++k) {
                    if (cancel_) return;
                    if (!chans[k].empty())
                        readChannels(*P->open[k].second, display, W, N, chans[k], fillv[k], threads,
                                     {}, fixes[k]);
                }
                P->ok = true;
            } catch (...) {
                // Any failure: beginFrame reads this frame as without prefetch and reports it
                // there.
            }
        });
}

}  // namespace kestrel::exr
