#pragma once
// Runs a compiled graph over a frame sequence: the frame schedule (a range, warm-up frames run
// without writing, resuming where a run stopped), frames that fail (fatal, or skipped with the
// history reset), a stop request between frames, and per-frame timings. The one frame loop of
// every front end (the CLI's run and bench, programs that embed the engine); it prints nothing:
// an observer reports progress and problems as the caller wishes.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "kestrel/Compiler.h"
#include "kestrel/Error.h"
#include "kestrel/Executor.h"

namespace kestrel {

struct SequenceOptions {
    /// The frames to compute, in order. Empty: the frames the graph's sources list.
    std::vector<int64_t> frames;
    /// Frames run before the first one without writing, so history (temporal filters) is as it
    /// would be in a longer run: a shot cut into chunks gives the unsplit run's frames.
    int warmup = 0;
    /// Skip the frames whose every sink reports its output written (Pass::frameWritten), up to the
    /// first missing one, replaying the frames before it without writing to rebuild history.
    bool resume = false;
    /// Frames replayed before the first missing frame on resume (at least `warmup`): the longest
    /// history a pass may need.
    int resumeHistory = 32;
    /// A FrameError (missing or corrupt input) skips the frame and resets history instead of
    /// ending the run.
    bool skipBadFrames = false;
    /// Camera cuts: history is reset before each of these frames, as at the start of a run, so
    /// a chunk whose warm-up contains the cut gives the unsplit run's frames from the cut on.
    std::set<int64_t> cuts;
    /// false: no frame writes its outputs (timing runs).
    bool writeOutputs = true;
    /// Polled after every frame: true ends the run there (an interrupt, a caller's failure).
    std::function<bool()> stop;
};

struct ScheduledFrame {
    int64_t frame = 0;
    bool write = true;  ///< false: warm-up or resume catch-up, sinks write nothing
};

struct SequencePlan {
    std::vector<int64_t> frames;           ///< the frames asked for (resolved)
    std::vector<ScheduledFrame> schedule;  ///< what runs, in order
    size_t alreadyWritten = 0;             ///< resume: frames found complete and not rewritten
    size_t replayed = 0;                   ///< resume: frames replayed before the first missing
    bool everythingWritten = false;        ///< resume: no frame is missing, nothing runs
    /// Without a range given: the frames found on both sides of each gap in the sequence (a
    /// missing frame, a folder named like one). History is reset before the second, as at a
    /// camera cut: carried across the gap it would blend two moments of the shot.
    std::vector<std::pair<int64_t, int64_t>> gaps;
};

struct FrameRecord {
    int64_t frame = 0;
    bool written = false;          ///< ran with its outputs written (not warm-up)
    double ms = 0;                 ///< wall time of the frame
    std::vector<PassTime> passes;  ///< per pass, in execution order
};

struct SkippedFrame {
    int64_t frame = 0;
    std::string error;  ///< the FrameError's message (names the frame, pass and file)
};

enum class SequenceEnd {
    Completed,  ///< every scheduled frame ran or was skipped
    Stopped,    ///< the stop callback asked to end
    Failed,     ///< beginRun or a frame failed (see `error`)
};

struct SequenceResult {
    SequenceEnd end = SequenceEnd::Completed;
    std::vector<FrameRecord> frames;    ///< every frame that ran, in order
    std::vector<SkippedFrame> skipped;  ///< frames skipped under skipBadFrames
    std::string error;                  ///< Failed: the message, one line
    /// Failed by a FrameError (one frame's input), not a fatal Error: front ends that map error
    /// classes (the Python module's exceptions) keep the class the message came from.
    bool frameError = false;
    int64_t lastFrame = 0;              ///< the last frame attempted (ran, skipped or failed)
    size_t written() const;
};

/// Hooks called as the run goes; the default of each does nothing. An exception thrown by a hook
/// ends the run: the executor's endRun is called and the exception leaves run().
class SequenceObserver {
public:
    virtual ~SequenceObserver() = default;
    /// Once before beginRun, with the schedule about to run (after resume).
    virtual void starting(const SequencePlan&) {}
    /// After each frame that ran; `exec` holds its marked outputs. `index` counts scheduled
    /// frames from 0 (skipped ones included).
    virtual void frameDone(const FrameRecord&, size_t /*index*/, const Executor& /*exec*/) {}
    /// A frame skipped under skipBadFrames; history is reset after it.
    virtual void frameSkipped(const SkippedFrame&) {}
};

/// The frames the graph's live sources list (the first that lists any), for a run without an
/// explicit range; empty when none does.
std::vector<int64_t> sourceFrames(const CompiledGraph& graph);

class SequenceRunner {
public:
    /// Resolves the frames (options.frames, else sourceFrames) and plans the warm-up. Throws
    /// Error when there is no frame to run.
    SequenceRunner(const CompiledGraph& graph, SequenceOptions options);

    /// The full schedule, before resume: every frame the run may read and write, for checks
    /// made before anything runs.
    const SequencePlan& plan() const { return plan_; }

    /// Applies resume, then beginRun, the frames, endRun. A failure of beginRun or of a frame
    /// (not skipped) ends the run as Failed; endRun is called unless beginRun failed.
    SequenceResult run(Executor& exec, SequenceObserver* observer = nullptr);

private:
    const CompiledGraph& graph_;
    SequenceOptions options_;
    SequencePlan plan_;
};

}  // namespace kestrel
