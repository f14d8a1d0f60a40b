#pragma once
// Per-frame context handed to every pass: which frame, whether history is valid, the scene's
// non-image data (camera and per-object matrices) for this and the previous frame, and the
// parallel-for helper. This is the one way a pass reaches per-frame non-image data.
#include <cstdint>
#include <map>
#include <string>

#include "kestrel/Format.h"
#include "kestrel/Math.h"
#include "kestrel/Parallel.h"

namespace kestrel {

/// Non-image data of one frame, filled by source passes (the loader) in frameExtent()/execute().
struct SceneData {
    bool hasCamera = false;
    /// World to camera space (OpenGL: camera looks down -Z).
    Mat4 worldToCamera = Mat4::identity();
    /// World to pixel coordinates: after the divide by w, x right and y DOWN in pixels, pixel
    /// (i, j) centred at (i + 0.5, j + 0.5). Composes viewport, projection and view.
    Mat4 worldToPixel = Mat4::identity();
    /// Object-to-world matrix per object id (the ids of the objectId image).
    std::map<int32_t, Mat4> objectToWorld;
};

/// Facts about the whole run, for provenance and logging.
struct RunInfo {
    std::string graphName;
    std::string graphPath;
    std::string provenance;  ///< compact JSON of the compiled graph's passes and parameters
    std::string kestrelVersion;
};

struct FrameContext {
    int64_t frameNumber = 0;  ///< the sequence's frame number (as in file names)
    int64_t frameIndex = 0;   ///< frames executed since the run started
    bool historyValid = false;  ///< false on the first frame and after a reset
    bool writeOutputs = true;   ///< false during warm-up and resume catch-up: sinks write nothing
    Extent extent{};
    SceneData* scene = nullptr;               ///< this frame's scene data (sources fill it)
    const SceneData* previousScene = nullptr;  ///< last frame's (hasCamera false if none)
    Parallel* parallel = nullptr;
    const RunInfo* run = nullptr;

    /// Run fn(y0, y1) over row ranges covering [0, height) on the engine's threads.
    template <class Fn>
    void parallelRows(int height, Fn&& fn) const {
        parallel->forRange(0, height, fn);
    }
};

}  // namespace kestrel
