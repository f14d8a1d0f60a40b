#pragma once
// Checks made before frame 1 so that a run never destroys what the user has: an output that
// names (or resolves to) a file the run reads, an output without a frame number that every
// frame would overwrite, two outputs on one file. All are usage errors (exit 2), in one line.
#include <kestrel/Graph.h>
#include <kestrel/Registry.h>

#include <cstdint>
#include <string>
#include <vector>

namespace kestrel::cli {

struct RunFrames {
    std::vector<int64_t> read;     ///< every frame the run loads (warm-up included)
    std::vector<int64_t> written;  ///< the frames whose outputs are written
};

/// Throws Error naming both patterns (or both files and the frame) when an output of a writer
/// (its path or preview) is an input of a loader or the --reference sequence: the same pattern,
/// or one that resolves to the same file through a symlink, '..' or a hard link. Throws Error
/// naming the pattern when one without a frame token would be written for several frames, and
/// naming both writers when two outputs (e.g. a path and a preview) are the same file.
void checkOutputsAreSafe(const GraphDesc& graph, const Registry& registry, const RunFrames& frames,
                         const std::string& reference);

}  // namespace kestrel::cli
