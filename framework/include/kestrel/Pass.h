#pragma once
// The pass API. A pass type is described by data (PassDesc: ports, formats, flags, parameters),
// so a JSON graph is validated completely before any pass runs. Three phases, three objects:
//   declare  - static PassDesc describe();               (what the type offers)
//   compile  - void resolve(ResolveContext&);             (adapt to what the scene provides)
//   execute  - void execute(FrameContext&, PassIO&);      (per frame; resources come from the
//   graph)
// A pass never allocates graph resources and keeps no temporal state in members: state that
// must survive to the next frame flows through history edges.
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "kestrel/Error.h"
#include "kestrel/Format.h"
#include "kestrel/FrameContext.h"
#include "kestrel/Image.h"
#include "kestrel/Params.h"

namespace kestrel {

enum class PortKind { Input, Output };

struct PortDesc {
    std::string name;
    PortKind kind = PortKind::Input;
    Format format = Format::Float;
    bool optional = false;  ///< input may stay unbound; the pass adapts
    bool history = false;   ///< input must be fed by a history edge (previous frame's value)
    std::string description;
    /// Outputs: the input whose memory this output may be given (see PassDesc::inPlaceOf).
    std::string inPlaceOf;
};

/// What a pass type declares: its ports and parameters. Built with the chainable helpers.
struct PassDesc {
    std::string type;
    std::string description;
    std::vector<PortDesc> ports;
    std::vector<ParamDesc> params;
    bool sink = false;  ///< writes outside the graph (files): always live, never pruned
    /// Inputs that passes of this type must share to run fused (see fuseOn).
    std::vector<std::string> fusedInputs;
    /// Whether fused members may differ in which outputs something consumes (see fuseOn).
    bool fusedOutputsMayDiffer = false;

    PassDesc(std::string type_, std::string description_)
        : type(std::move(type_)), description(std::move(description_)) {}

    PassDesc& input(std::string name, Format f, std::string desc);
    PassDesc& optionalInput(std::string name, Format f, std::string desc);
    /// Previous-frame value through a history edge; always optional (invalid on first frame).
    PassDesc& historyInput(std::string name, Format f, std::string desc);
    PassDesc& output(std::string name, Format f, std::string desc);
    /// The last declared output may be written into the memory of `input` (same format) when
    /// this pass is that input's last reader this frame: the compiler then gives both one set of
    /// planes (saving the output's memory). The pass promises to be pointwise on that pair: it
    /// reads each pixel of the input before writing the same pixel of the output, and no other
    /// pixel of the input (no neighbourhood), except in an earlier phase of execute that has
    /// finished before the first write (AntiLag reads every pixel's validity first). Kernels must
    /// not declare the two pointers __restrict.
    PassDesc& inPlaceOf(std::string input);
    /// Passes of this type may run fused (Pass::executeFused) when these inputs of each come
    /// from the same outputs (or are all unbound): the work on them is then done once.
    /// FusedOutputs::Same (the default) fuses only members whose consumed outputs are the same;
    /// MayDiffer also fuses members that leave different outputs unconsumed (absent in their
    /// PassIO), which executeFused then handles.
    enum class FusedOutputs { Same, MayDiffer };
    PassDesc& fuseOn(std::vector<std::string> inputs, FusedOutputs outputs = FusedOutputs::Same);

    PassDesc& paramFloat(std::string name, double def, double min, double max, std::string desc);
    PassDesc& paramInt(std::string name, int64_t def, int64_t min, int64_t max, std::string desc);
    PassDesc& paramBool(std::string name, bool def, std::string desc);
    PassDesc& paramString(std::string name, std::string def, std::string desc);
    PassDesc& paramEnum(std::string name, std::string def, std::vector<std::string> choices,
                        std::string desc);

    const PortDesc* findPort(std::string_view name) const;
    const ParamDesc* findParam(std::string_view name) const;
};

/// A port as a typed declaration returns it (kestrel/Declare.h): its place in the pass type's
/// PassDesc, and its name. Passes read and write through handles, so a misspelt port does not
/// compile and PassIO finds it by index.
template <PortKind K>
struct PortHandle {
    int index = -1;
    std::string name;
};
using InputPort = PortHandle<PortKind::Input>;
using OutputPort = PortHandle<PortKind::Output>;

/// Compile-time view of one pass instance: which inputs the scene and graph can feed, and how
/// the pass adapts. Unbound optional inputs are never read, allocated or computed.
class ResolveContext {
public:
    virtual ~ResolveContext() = default;
    /// Whether an input is connected to a producer that will exist.
    virtual bool isBound(std::string_view input) const = 0;
    /// Why an input is not bound: where the missing data comes from (a source's absent output
    /// and its reason, e.g. the loader's missing channel), for a pass's own absent reasons;
    /// empty when it is bound.
    virtual std::string unboundReason(std::string_view /*input*/) const { return {}; }
    /// Declare that `output` is exactly `input` (identity). Consumers are rewired to the
    /// input's producer; when every used output is forwarded the pass is left out.
    virtual void forward(std::string_view output, std::string_view input) = 0;
    /// Declare that `output` will not be produced (e.g. the scene lacks the channel).
    virtual void setAbsent(std::string_view output, std::string reason) = 0;
    /// Declare that a connected input will not be read for this scene (e.g. world positions
    /// when motion vectors are given): the compiler disconnects it, so a producer feeding only
    /// this input is left out and a source does not read the channel. The reason is logged.
    virtual void ignoreInput(std::string_view /*input*/, std::string /*reason*/) {}
    /// A line for the run log: what the pass adapted and why.
    virtual void note(std::string message) = 0;
    /// Scene facts a source states at compile time ("antiAliased" = "true"), for passes
    /// downstream to adapt to without reading an image: resolve runs in dependency order, so a
    /// source has stated its facts before any pass fed by it resolves. Listed in the report.
    virtual void setFact(std::string /*key*/, std::string /*value*/) {}
    /// A fact some source stated, or nullopt.
    virtual std::optional<std::string> fact(std::string_view /*key*/) const { return std::nullopt; }
    bool isBound(const InputPort& p) const { return isBound(p.name); }
    std::string unboundReason(const InputPort& p) const { return unboundReason(p.name); }
    void forward(const OutputPort& o, const InputPort& i) { forward(o.name, i.name); }
    void setAbsent(const OutputPort& o, std::string reason) {
        setAbsent(o.name, std::move(reason));
    }
    void ignoreInput(const InputPort& p, std::string reason) {
        ignoreInput(p.name, std::move(reason));
    }
    /// Sequence facts a source needs at compile time.
    virtual int64_t firstFrame() const = 0;
    virtual std::string_view passName() const = 0;
};

/// Run-level hook context (before frame 1).
struct RunContext {
    const RunInfo* run = nullptr;
    int64_t firstFrame = 0;
    int64_t lastFrame = 0;
};

/// Per-frame access to a pass's bound resources, by port name (a handful of ports: the linear
/// name match costs nanoseconds per frame and is never done per pixel).
class PassIO {
public:
    virtual ~PassIO() = default;
    /// Bound and, for a history input, valid this frame.
    virtual bool hasInput(std::string_view name) const = 0;
    /// Throws Error if the input is unbound (or an invalid history).
    virtual const ImageView& input(std::string_view name) const = 0;
    /// For history inputs: connected and valid (false on the first frame and after a reset).
    virtual bool historyValid(std::string_view name) const = 0;
    /// Whether anyone consumes this output (unused outputs are not allocated).
    virtual bool hasOutput(std::string_view name) const = 0;
    virtual const ImageView& output(std::string_view name) = 0;
    /// Working memory that costs nothing: the transient planes of the memory plan that no
    /// resource occupies while this pass runs (Frostbite's frame graph aliases a pass's scratch
    /// the same way). Each holds FrameContext::extent.pixels() floats, 64-byte aligned; contents
    /// are undefined on entry and belong to later passes after execute returns, so use them only
    /// within execute, on its own threads. Empty where the plan has no idle plane (and in tests).
    virtual std::span<float* const> idlePlanes() const { return {}; }

    /// The same by handle (kestrel/Declare.h): the executor finds the port by its index; other
    /// implementations (test harnesses) by its name.
    virtual bool has(const InputPort& p) const { return hasInput(p.name); }
    virtual const ImageView& input(const InputPort& p) const { return input(p.name); }
    virtual bool historyValid(const InputPort& p) const { return historyValid(p.name); }
    virtual bool has(const OutputPort& p) const { return hasOutput(p.name); }
    virtual const ImageView& output(const OutputPort& p) { return output(p.name); }
};

/// The relative step of the scene's stored depth (the fact kDepthPrecisionFact, clamped to
/// [0, 1]); 0 where no source states it (float depth). Passes that compare depths widen their
/// tolerance by it; with a note naming the step when it is stated.
float depthPrecision(ResolveContext& rc);

class Pass {
public:
    virtual ~Pass() = default;
    /// Compile time: adapt to bound inputs (forward, mark outputs absent). Sources probe the
    /// scene here. Throw Error for a configuration that cannot work.
    virtual void resolve(ResolveContext&) {}
    /// Once before the first frame of a run, for live passes (check output dirs, open files).
    virtual void beginRun(const RunContext&) {}
    /// Sources: report this frame's extent (and fill ctx.scene). Others return nullopt.
    /// Throw FrameError for a missing or unreadable frame.
    virtual std::optional<Extent> beginFrame(FrameContext&) { return std::nullopt; }
    virtual void execute(FrameContext& ctx, PassIO& io) = 0;
    /// Fusion, as Granite's render graph merges compatible render passes into one: live passes
    /// of one type that declares PassDesc::fuseOn, whose fuseOn inputs come from the same
    /// outputs, whose fusionKey() is equal and not empty, and none of which depends on another,
    /// run as one step of the execution order (their memory is planned as one step's).
    /// Empty (the default): never fused. Known after resolve().
    virtual std::string fusionKey() const { return {}; }
    /// Runs a fused step: `passes` (this one first) with their PassIO, in execution order.
    /// The default runs each one's execute; results must equal that. The members' idlePlanes
    /// are the same planes: members run at once must not both use them.
    virtual void executeFused(FrameContext& ctx, std::span<Pass* const> passes,
                              std::span<PassIO* const> ios);
    /// Sources: frame numbers available when the user gives no range (empty: unknown).
    virtual std::vector<int64_t> availableFrames() const { return {}; }
    /// Sources: every file this frame reads, the sidecars included (GAMES202's normal_, depth_
    /// ... files and matrix_N.mat, a Blender render's camera.json), each with the parameter
    /// that names it ("path", "camera"), so that no output of the run replaces one. Known
    /// after resolve(); empty: the pass reads no files.
    virtual std::vector<std::pair<std::string, std::string>> filesRead(
        int64_t /*frameNumber*/) const {
        return {};
    }
    /// Sinks: whether this frame's output already exists, complete and intact (for --resume and
    /// farm check). `provenance`: the graph's (CompiledGraph::provenanceJson), which an output
    /// must have been written with; empty: any will do.
    virtual bool frameWritten(int64_t /*frameNumber*/, const std::string& /*provenance*/) const {
        return false;
    }
    /// Sinks: the provenance (CompiledGraph::provenanceJson) this frame's existing output
    /// records; empty when it records none or cannot be read. farm check says from it which
    /// graph or parameters made an output that is not the plan's.
    virtual std::string recordedProvenance(int64_t /*frameNumber*/) const { return {}; }
    /// Sinks: called at the end of a run (close files, print summaries).
    virtual void endRun() {}
};

}  // namespace kestrel
