#pragma once
// Runs a compiled graph frame after frame: sizes resources to the frame, executes passes in
// order, times each one, swaps history buffers at frame end.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "kestrel/Compiler.h"
#include "kestrel/Parallel.h"

namespace kestrel {

struct PassTime {
    std::string pass;
    double ms = 0;
};

struct MemoryStats {
    size_t transientPlanes = 0;  ///< physical planes backing transient resources
    size_t historyPlanes = 0;    ///< planes of history resources (every buffer allocated)
    size_t markedPlanes = 0;     ///< planes of marked outputs
    size_t bytes = 0;            ///< all graph resource memory now allocated
    size_t peakBytes = 0;
};

class Executor {
public:
    /// `defaultExtent` sizes frames when no source pass reports an extent (tests, generators).
    Executor(CompiledGraph& graph, Parallel& parallel, RunInfo run = {},
             Extent defaultExtent = {0, 0});
    ~Executor();

    /// Calls beginRun on live passes (fails before frame 1 for unwritable outputs etc.).
    void beginRun(int64_t firstFrame, int64_t lastFrame);
    /// Executes one frame. Throws FrameError (frame-local) or Error; a frame that throws leaves
    /// history untouched and the next frame starts with history invalid.
    void runFrame(int64_t frameNumber, bool writeOutputs = true);
    /// Marks all history invalid for the next frame (camera cut, skipped frame).
    void resetHistory();
    void endRun();

    /// Wall time of each executed pass in the last frame, in execution order.
    const std::vector<PassTime>& lastTimes() const;
    double lastFrameMs() const;
    /// A marked output ("pass.port") of the last frame; throws Error if not marked.
    ImageView output(std::string_view passPort) const;
    const MemoryStats& memory() const;
    Extent extent() const;
    int64_t framesRun() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel
