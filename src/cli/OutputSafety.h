#pragma once
// Checks made before frame 1 so that a run never destroys what the user has: an output that
// names (or resolves to) a file the run reads, an output without a frame number that every
// frame would overwrite, two outputs on one file. All are usage errors (exit 2), in one line.
#include <kestrel/Compiler.h>
#include <kestrel/Graph.h>
#include <kestrel/Registry.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace kestrel::cli {

struct RunFrames {
    std::vector<int64_t> read;     ///< every frame the run loads (warm-up included)
    std::vector<int64_t> written;  ///< the frames whose outputs are written
};

/// Every file a command reads in this invocation (the graph and its includes, every frame and
/// sidecar of its sources, references, plans), each with what names it: the one list that each
/// file the command writes is checked against before its first write (docs/errors.md).
class FilesRead {
public:
    FilesRead();
    ~FilesRead();
    void add(const std::string& file, const std::string& label);
    /// The graph file and every file it includes or extends.
    void addGraph(const GraphDesc& graph);
    /// Every file each live pass of `compiled` reads for `frames` (Pass::filesRead).
    void addSources(const CompiledGraph& compiled, const std::vector<int64_t>& frames);
    /// Throws Error "output FILE (LABEL) is ...: writing would destroy it; FIX" when `file` is one
    /// of them: the same name, or the same file through a symlink, '..' or a hard link.
    void check(const std::string& file, const std::string& label, const std::string& fix) const;

private:
    struct Index;
    std::unique_ptr<Index> index_;
};

/// Throws Error naming both patterns (or both files and the frame) when an output of a writer
/// (its path or preview) is an input of a loader or the --reference sequence: the same pattern,
/// or one that resolves to the same file through a symlink, '..' or a hard link. Throws Error
/// naming the pattern when one without a frame token would be written for several frames, and
/// naming both writers when two outputs (e.g. a path and a preview) are the same file.
/// With `compiled`, the files its sources read (GAMES202's sibling files, camera.json) and the
/// graph's own files are inputs too.
void checkOutputsAreSafe(const GraphDesc& graph, const Registry& registry, const RunFrames& frames,
                         const std::string& reference, const CompiledGraph* compiled = nullptr);

/// The files the graph's writers (their path and preview) write for `frames`.
std::vector<std::string> outputFiles(const GraphDesc& graph, const Registry& registry,
                                     const std::vector<int64_t>& frames);

/// Removes the temporaries (`.NAME.tmp-PID`, ExrWriter.cpp) that a killed writer left beside
/// `files`: those whose process is not running on this machine and that were last written at
/// least `minAge` ago. One log line each; returns how many. A live writer's are kept: another
/// run may be writing the same frame.
int removeStaleTemporaries(const std::vector<std::string>& files, std::chrono::seconds minAge);

}  // namespace kestrel::cli
