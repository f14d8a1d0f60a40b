#pragma once
// The graph compiler: validate -> instantiate -> resolve what the scene provides -> prune ->
// order -> plan memory. Names ("pass.port") are resolved here, once, into integer handles.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "kestrel/Graph.h"
#include "kestrel/Pass.h"
#include "kestrel/Registry.h"

namespace kestrel {

struct CompileOptions {
    int64_t firstFrame = 0;  ///< handed to sources so they can probe the scene
    /// Only validate: do not call resolve() (no files opened), skip scene adaptation.
    bool validateOnly = false;
    /// Let outputs declared PassDesc::inPlaceOf take over their input's memory where allowed;
    /// false gives every output memory of its own (to check a pass's in-place declaration).
    bool inPlace = true;
    /// Run compatible passes fused (Pass::executeFused); false runs each on its own (results
    /// are the same; to measure what fusion saves).
    bool fuse = true;
    /// Let transient resources live in history memory while it is idle: last frame's value once
    /// its last reader has run, until this frame's is written over it (or to the end of the
    /// frame, where a second buffer holds this frame's). False keeps history memory to itself.
    bool historyIdle = true;
};

/// Why a pass is not executed.
struct LeftOutPass {
    std::string pass;
    std::string reason;
    /// Elided as the identity for its own parameters (AntiLag with enabled false, an A-Trous
    /// iteration past `iterations`), not for a fact of the scene the pass noted (TAA on a
    /// point-sampled render): an override of its parameters took effect.
    bool forItsParameters = false;
};

struct CompileReport {
    std::vector<std::string> notes;               ///< adaptation notes from resolve()
    std::vector<LeftOutPass> pruned;              ///< contributes to no output
    std::vector<LeftOutPass> elided;              ///< identity for this scene (outputs forwarded)
    std::vector<std::string> absent;              ///< "pass.port: reason" outputs the scene lacks
    std::map<std::string, std::string> facts;     ///< scene facts sources stated (ResolveContext)
    std::vector<std::vector<std::string>> fused;  ///< passes run as one step (executeFused)
};

/// Channel `channel` of history resource `resource`: the buffer holding last frame's value (a
/// double-buffered resource's other buffer holds this frame's).
struct HistoryPlane {
    int resource = -1;
    int channel = 0;
    bool operator==(const HistoryPlane&) const = default;
};

/// A resource slot: one produced output, possibly sharing memory with others (aliasing).
struct ResourceInfo {
    std::string producer;  ///< "pass.port"
    Format format = Format::Float;
    bool history = false;  ///< read next frame (persists across frames)
    /// A history resource needs a second buffer only if some pass reads last frame's value at
    /// or after the producer writes this frame's. When every history reader runs first, the
    /// one buffer is read (last frame) and then overwritten (this frame).
    bool doubleBuffered = false;
    int lastHistoryRead = -1;       ///< step of the last pass reading last frame's value
    bool marked = false;            ///< a graph output, kept to the end of the frame
    int firstUse = 0, lastUse = 0;  ///< steps (execution indices where nothing is fused)
    std::vector<int> planes;        ///< physical plane slots (transient) it occupies
    /// The resource whose planes this one took over (written in place by its producer, see
    /// PassDesc::inPlaceOf), else -1.
    int inPlaceOf = -1;
    /// Where a transient resource lives in history memory while that is idle (else empty, and
    /// `planes` holds it): per channel, a plane of a history resource
    /// (CompileOptions::historyIdle).
    std::vector<HistoryPlane> historyPlanes;
};

class CompiledGraph;

/// Throws GraphError with every problem found, or Error for a scene the graph cannot run on.
std::unique_ptr<CompiledGraph> compileGraph(const GraphDesc& graph, const Registry& registry,
                                            const CompileOptions& options = {});

/// The compiled graph: live passes in execution order with their bindings and memory plan.
/// Executed by an Executor.
class CompiledGraph {
public:
    ~CompiledGraph();
    const GraphDesc& desc() const;
    const CompileReport& report() const;
    /// Live pass names in execution order.
    std::vector<std::string> executionOrder() const;
    const std::vector<ResourceInfo>& resources() const;
    /// Number of distinct transient planes the memory plan needs (after aliasing).
    int transientPlaneCount() const;
    /// Planes the resources would need without aliasing.
    int unaliasedPlaneCount() const;
    /// The transient planes idle while the pass at execution index k runs (PassIO::idlePlanes).
    const std::vector<int>& idlePlanes(size_t k) const;
    /// The step of the pass at execution index k: passes fused into one step are adjacent in
    /// the execution order and share it (CompileReport::fused); -1 past the end.
    int stepOf(size_t k) const;
    /// Graphviz DOT: live and pruned passes, history edges dashed, shared memory noted.
    std::string toDot() const;
    /// Compact JSON of the passes and their effective parameters (provenance).
    std::string provenanceJson() const;
    /// Live passes of a given type (e.g. sources, sinks), for the CLI.
    std::vector<std::pair<std::string, Pass*>> passesOfType(const std::string& type) const;
    std::vector<std::pair<std::string, Pass*>> sinks() const;
    std::vector<std::pair<std::string, Pass*>> livePasses() const;

    struct Impl;
    Impl& impl() { return *impl_; }
    const Impl& impl() const { return *impl_; }
    explicit CompiledGraph(std::unique_ptr<Impl> impl);

private:
    std::unique_ptr<Impl> impl_;
};

/// The overrides (`pass.param=value` as applyOverride takes them, already applied to the graph
/// `compiled` was built from) that set only passes this scene leaves out: tuning that would
/// silently do nothing. One Diagnostic each (path: the option as typed), saying why those
/// passes are left out and which live instance or pattern would take the value.
std::vector<Diagnostic> unusedOverrides(const CompiledGraph& compiled,
                                        const std::vector<std::string>& assignments,
                                        const Registry& registry,
                                        const std::string& option = "--set");

}  // namespace kestrel
