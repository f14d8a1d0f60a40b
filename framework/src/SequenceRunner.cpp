#include "kestrel/SequenceRunner.h"

#include <algorithm>
#include <cstdint>

namespace kestrel {

namespace {

/// Warm-up frames before the range, at the range's own step, then the range.
std::vector<ScheduledFrame> scheduleWithWarmup(const std::vector<int64_t>& frames, int warmup) {
    std::vector<ScheduledFrame> schedule;
    if (warmup > 0) {
        const int64_t step = frames.size() > 1 ? std::max<int64_t>(1, frames[1] - frames[0]) : 1;
        for (int i = warmup; i >= 1; --i) schedule.push_back({frames.front() - i * step, false});
    }
    for (int64_t f : frames) schedule.push_back({f, true});
    return schedule;
}

/// The gaps of a sequence found on disk: consecutive frames further apart than its step (the
/// smallest distance between two of them).
std::vector<std::pair<int64_t, int64_t>> gapsIn(const std::vector<int64_t>& frames) {
    std::vector<std::pair<int64_t, int64_t>> gaps;
    if (frames.size() < 2) return gaps;
    int64_t step = INT64_MAX;
    for (size_t i = 1; i < frames.size(); ++i) step = std::min(step, frames[i] - frames[i - 1]);
    for (size_t i = 1; i < frames.size(); ++i)
        if (frames[i] - frames[i - 1] > step) gaps.push_back({frames[i - 1], frames[i]});
    return gaps;
}

bool everySinkWrote(const std::vector<std::pair<std::string, Pass*>>& sinks, int64_t frame,
                    const std::string& provenance) {
    if (sinks.empty()) return false;  // nothing to look at: the frame is not known to be done
    return std::all_of(sinks.begin(), sinks.end(),
                       [&](const auto& s) { return s.second->frameWritten(frame, provenance); });
}

/// Drops the frames before the first one some sink lacks, keeping the `history` frames just
/// before it as catch-up (run, not written) so temporal passes see the history they would have.
void resume(SequencePlan& plan, const CompiledGraph& graph, size_t history) {
    const auto sinks = graph.sinks();
    // An output of another graph or other parameters is not this run's frame.
    const std::string provenance = graph.provenanceJson();
    auto& s = plan.schedule;
    size_t firstMissing = s.size();
    for (size_t i = 0; i < s.size(); ++i)
        if (s[i].write && !everySinkWrote(sinks, s[i].frame, provenance)) {
            firstMissing = i;
            break;
        }
    plan.alreadyWritten = size_t(
        std::count_if(s.begin(), s.begin() + long(firstMissing), [](auto& f) { return f.write; }));
    if (firstMissing == s.size()) {
        plan.everythingWritten = true;
        s.clear();
        return;
    }
    const size_t replay = std::min(firstMissing, history);
    std::vector<ScheduledFrame> resumed(s.begin() + long(firstMissing - replay), s.end());
    for (size_t i = 0; i < replay; ++i) resumed[i].write = false;
    plan.replayed = replay;
    s = std::move(resumed);
}

enum class Outcome { Ran, Skipped, Failed };

/// Runs one scheduled frame, recording its time, its skip or the run's failure in `result`.
/// Only the executor's errors are caught here: an observer's are the observer's.
Outcome runOne(Executor& exec, ScheduledFrame f, const SequenceOptions& o, SequenceResult& result) {
    if (o.cuts.count(f.frame)) exec.resetHistory();
    try {
        exec.runFrame(f.frame, f.write && o.writeOutputs);
    } catch (const FrameError& e) {
        if (o.skipBadFrames) {
            result.skipped.push_back({f.frame, e.what()});
            exec.resetHistory();
            return Outcome::Skipped;
        }
        result.end = SequenceEnd::Failed;
        result.error = e.what();
        result.frameError = true;
        return Outcome::Failed;
    } catch (const Error& e) {
        result.end = SequenceEnd::Failed;
        result.error = e.what();
        return Outcome::Failed;
    }
    result.frames.push_back(
        {f.frame, f.write && o.writeOutputs, exec.lastFrameMs(), exec.lastTimes()});
    return Outcome::Ran;
}

}  // namespace

size_t SequenceResult::written() const {
    return size_t(std::count_if(frames.begin(), frames.end(), [](auto& f) { return f.written; }));
}

std::vector<int64_t> sourceFrames(const CompiledGraph& graph) {
    for (const auto& [name, pass] : graph.livePasses()) {
        auto frames = pass->availableFrames();
        if (!frames.empty()) return frames;
    }
    return {};
}

SequenceRunner::SequenceRunner(const CompiledGraph& graph, SequenceOptions options)
    : graph_(graph), options_(std::move(options)) {
    plan_.frames = options_.frames.empty() ? sourceFrames(graph_) : options_.frames;
    if (plan_.frames.empty())
        throw Error("no frames to run: none given and no source lists its frames");
    if (options_.frames.empty()) {  // a range given is the user's; frames found may have holes
        plan_.gaps = gapsIn(plan_.frames);
        for (const auto& gap : plan_.gaps) options_.cuts.insert(gap.second);
    }
    plan_.schedule = scheduleWithWarmup(plan_.frames, options_.warmup);
}

SequenceResult SequenceRunner::run(Executor& exec, SequenceObserver* observer) {
    SequenceObserver none;
    SequenceObserver& obs = observer ? *observer : none;
    SequencePlan plan = plan_;
    if (options_.resume)
        resume(plan, graph_, size_t(std::max(options_.warmup, options_.resumeHistory)));
    obs.starting(plan);

    SequenceResult result;
    try {
        exec.beginRun(plan.frames.front(), plan.frames.back());
    } catch (const Error& e) {
        result.end = SequenceEnd::Failed;
        result.error = e.what();
        return result;
    }
    try {
        for (size_t i = 0; i < plan.schedule.size(); ++i) {
            const ScheduledFrame f = plan.schedule[i];
            result.lastFrame = f.frame;
            const Outcome outcome = runOne(exec, f, options_, result);
            if (outcome == Outcome::Failed) break;
            if (outcome == Outcome::Ran)
                obs.frameDone(result.frames.back(), i, exec);
            else
                obs.frameSkipped(result.skipped.back());
            if (options_.stop && options_.stop()) {
                result.end = SequenceEnd::Stopped;
                break;
            }
        }
    } catch (...) {  // a hook threw: finish the run, then let the caller have it
        try {
            exec.endRun();
        } catch (...) {  // the hook's failure is the one to report
        }
        throw;
    }
    exec.endRun();
    return result;
}

}  // namespace kestrel
