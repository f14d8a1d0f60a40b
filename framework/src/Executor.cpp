#include "kestrel/Executor.h"

#include <chrono>
#include <new>

#include "CompilerImpl.h"
#include "kestrel/Log.h"

namespace kestrel {

namespace {

using Clock = std::chrono::steady_clock;

/// Per-pass binding of ports to images, rebuilt when resources are (re)allocated.
class NodeIO final : public PassIO {
public:
    struct Slot {
        const PortDesc* port = nullptr;
        ImageView view;
        bool bound = false;
        bool valid = false;
    };
    std::vector<Slot> slots;
    std::string passName;
    std::vector<float*> idle;  ///< PassIO::idlePlanes

    const Slot* find(std::string_view name, PortKind kind) const {
        for (const auto& s : slots)
            if (s.port->kind == kind && s.port->name == name) return &s;
        return nullptr;
    }
    bool hasInput(std::string_view name) const override {
        const Slot* s = find(name, PortKind::Input);
        return s && s->bound && s->valid;
    }
    const ImageView& input(std::string_view name) const override {
        const Slot* s = find(name, PortKind::Input);
        if (!s) throw Error("pass '" + passName + "' has no input '" + std::string(name) + "'");
        if (!s->bound || !s->valid)
            throw Error("pass '" + passName + "' read input '" + std::string(name) +
                        "', which is not bound this frame (check hasInput first)");
        return s->view;
    }
    bool historyValid(std::string_view name) const override {
        const Slot* s = find(name, PortKind::Input);
        return s && s->port->history && s->bound && s->valid;
    }
    bool hasOutput(std::string_view name) const override {
        const Slot* s = find(name, PortKind::Output);
        return s && s->bound;
    }
    const ImageView& output(std::string_view name) override {
        const Slot* s = find(name, PortKind::Output);
        if (!s) throw Error("pass '" + passName + "' has no output '" + std::string(name) + "'");
        if (!s->bound)
            throw Error("pass '" + passName + "' wrote output '" + std::string(name) +
                        "', which nothing consumes (check hasOutput first)");
        return s->view;
    }
    std::span<float* const> idlePlanes() const override { return idle; }

    // By handle: the slots are in the PassDesc's port order, so a handle's index is its slot.
    const Slot* at(int index, PortKind kind) const {
        return index >= 0 && size_t(index) < slots.size() && slots[size_t(index)].port->kind == kind
                   ? &slots[size_t(index)]
                   : nullptr;
    }
    bool has(const InputPort& p) const override {
        const Slot* s = at(p.index, PortKind::Input);
        return s && s->bound && s->valid;
    }
    const ImageView& input(const InputPort& p) const override {
        const Slot* s = at(p.index, PortKind::Input);
        if (!s || !s->bound || !s->valid) return input(std::string_view(p.name));  // its error
        return s->view;
    }
    bool historyValid(const InputPort& p) const override {
        const Slot* s = at(p.index, PortKind::Input);
        return s && s->port->history && s->bound && s->valid;
    }
    bool has(const OutputPort& p) const override {
        const Slot* s = at(p.index, PortKind::Output);
        return s && s->bound;
    }
    const ImageView& output(const OutputPort& p) override {
        const Slot* s = at(p.index, PortKind::Output);
        if (!s || !s->bound) return output(std::string_view(p.name));  // its error
        return s->view;
    }
};

}  // namespace

struct Executor::Impl {
    CompiledGraph& graph;
    CompiledGraph::Impl& g;
    Parallel& parallel;
    RunInfo run;
    Extent defaultExtent;
    Extent extent{};
    std::vector<PlaneStorage> transient;  // physical planes shared by transient resources
    // History resources: double-buffered ones are written to hist[current] and read last
    // frame's value from hist[1 - current]; single-buffered ones (every reader of last frame's
    // value runs before the producer) live in hist[0] only, read and then rewritten.
    std::vector<std::array<PlaneStorage, 4>> hist[2];
    int current = 0;
    bool historyValid = false;
    std::vector<NodeIO> io;  // per executed pass
    std::vector<PassTime> times;
    double frameMs = 0;
    SceneData scene[2];
    int sceneCur = 0;
    bool hasPrevScene = false;
    MemoryStats memory;
    int64_t frames = 0;

    Impl(CompiledGraph& cg, Parallel& p, RunInfo r, Extent e)
        : graph(cg), g(cg.impl()), parallel(p), run(std::move(r)), defaultExtent(e) {
        if (run.provenance.empty()) run.provenance = graph.provenanceJson();
        if (run.graphName.empty()) run.graphName = g.desc.name;
        io.resize(g.order.size());
        for (size_t k = 0; k < g.order.size(); ++k) {
            const NodeState& n = g.nodes[size_t(g.order[k])];
            io[k].passName = n.name;
            for (const auto& port : n.type->desc.ports)
                io[k].slots.push_back({&port, {}, false, false});
        }
    }

    ImageView viewOf(int r, bool previous) {
        const ResourceInfo& res = g.resources[size_t(r)];
        ImageView v;
        v.extent = extent;
        v.format = res.format;
        for (int c = 0; c < channelCount(res.format); ++c) {
            if (res.history) {
                int buf = !res.doubleBuffered ? 0 : previous ? 1 - current : current;
                v.planes[size_t(c)] = hist[buf][size_t(r)][size_t(c)].get();
            } else if (!res.historyPlanes.empty()) {  // last frame's buffer, idle by now
                const HistoryPlane& hp = res.historyPlanes[size_t(c)];
                const int buf = g.resources[size_t(hp.resource)].doubleBuffered ? 1 - current : 0;
                v.planes[size_t(c)] = hist[buf][size_t(hp.resource)][size_t(hp.channel)].get();
            } else {
                v.planes[size_t(c)] = transient[size_t(res.planes[size_t(c)])].get();
            }
        }
        return v;
    }

    void allocate(Extent e) {
        extent = e;
        size_t px = e.pixels();
        transient.clear();
        for (int i = 0; i < g.transientPlanes; ++i) transient.push_back(allocatePlane(px));
        size_t histPlanes = 0;
        for (int b = 0; b < 2; ++b) {
            hist[b].clear();
            hist[b].resize(g.resources.size());
            for (size_t r = 0; r < g.resources.size(); ++r) {
                const ResourceInfo& res = g.resources[r];
                if (!res.history) continue;
                for (int c = 0; c < channelCount(res.format); ++c) {
                    if (b == 1 && !res.doubleBuffered) continue;  // one buffer: hist[0]
                    hist[b][r][size_t(c)] = allocatePlane(px);
                    ++histPlanes;
                }
            }
        }
        for (size_t k = 0; k < g.order.size(); ++k) {  // PassIO::idlePlanes
            io[k].idle.clear();
            for (int pl : graph.idlePlanes(k)) io[k].idle.push_back(transient[size_t(pl)].get());
        }
        memory.transientPlanes = size_t(g.transientPlanes);
        memory.historyPlanes = histPlanes;
        memory.markedPlanes = 0;
        for (int r : g.markedResource)
            memory.markedPlanes += size_t(channelCount(g.resources[size_t(r)].format));
        memory.bytes = (memory.transientPlanes + memory.historyPlanes) * px * sizeof(float);
        memory.peakBytes = std::max(memory.peakBytes, memory.bytes);
        historyValid = false;
    }

    /// Points every port at this frame's buffers (history buffers alternate per frame).
    void bind() {
        for (size_t k = 0; k < g.order.size(); ++k) {
            const NodeState& n = g.nodes[size_t(g.order[k])];
            for (size_t p = 0; p < io[k].slots.size(); ++p) {
                auto& slot = io[k].slots[p];
                int r = n.portResource[p];
                slot.bound = r >= 0;
                if (!slot.bound) continue;
                bool prev = slot.port->kind == PortKind::Input && n.portHistory[p];
                slot.view = viewOf(r, prev);
                slot.valid = !prev || historyValid;
            }
        }
    }
};

Executor::Executor(CompiledGraph& graph, Parallel& parallel, RunInfo run, Extent defaultExtent)
    : impl_(std::make_unique<Impl>(graph, parallel, std::move(run), defaultExtent)) {}
Executor::~Executor() = default;

void Executor::beginRun(int64_t firstFrame, int64_t lastFrame) {
    RunContext rc{&impl_->run, firstFrame, lastFrame};
    for (int v : impl_->g.order) {
        auto& n = impl_->g.nodes[size_t(v)];
        try {
            n.pass->beginRun(rc);
        } catch (const std::exception& e) {
            throw Error("pass '" + n.name + "': " + e.what());
        }
    }
}

namespace {
/// The frame files `n` reads for `frame` ("a.exr, b.exr"; "" for a pass that reads none; its
/// "path" parameter's, not sidecars): what an out-of-memory error names, since a forged data
/// window is the usual cause.
std::string filesOf(const NodeState& n, int64_t frame) {
    std::string list;
    try {
        for (const auto& [file, param] : n.pass->filesRead(frame))
            if (param == "path") list += (list.empty() ? "" : ", ") + file;
    } catch (const std::exception&) {  // naming the files is a courtesy, never a second error
    }
    return list;
}

std::string sizeText(Extent e) {
    return std::to_string(e.width) + "x" + std::to_string(e.height);
}
}  // namespace

void Executor::runFrame(int64_t frameNumber, bool writeOutputs) {
    Impl& m = *impl_;
    SceneData& scene = m.scene[m.sceneCur];
    scene = SceneData{};
    SceneData& prevScene = m.scene[1 - m.sceneCur];
    if (!m.hasPrevScene) prevScene = SceneData{};

    FrameContext ctx;
    ctx.frameNumber = frameNumber;
    ctx.frameIndex = m.frames;
    ctx.writeOutputs = writeOutputs;
    ctx.scene = &scene;
    ctx.previousScene = &prevScene;
    ctx.parallel = &m.parallel;
    ctx.run = &m.run;

    // `fusedWith`: the other passes of a fused step, named too (any of them may have failed).
    auto fail = [&](const NodeState& n, const std::exception& e,
                    const std::string& fusedWith = {}) {
        // A failed frame leaves history unusable: the next frame starts fresh.
        m.historyValid = false;
        m.hasPrevScene = false;
        std::string msg = "frame " + std::to_string(frameNumber) + ", pass '" + n.name + "' (" +
                          n.type->desc.type +
                          (fusedWith.empty() ? "" : ", fused with " + fusedWith) + "): " + e.what();
        if (dynamic_cast<const std::bad_alloc*>(&e)) {
            const std::string files = filesOf(n, frameNumber);
            msg += " (out of memory" + (files.empty() ? "" : " reading " + files) + ")";
        }
        if (dynamic_cast<const FrameError*>(&e)) throw FrameError(msg);
        throw Error(msg);
    };

    std::optional<Extent> extent;
    const NodeState* sizer = nullptr;  // the source whose file gave the frame's size
    for (int v : m.g.order) {
        auto& n = m.g.nodes[size_t(v)];
        try {
            ctx.extent = extent.value_or(m.extent);
            auto e = n.pass->beginFrame(ctx);
            if (e && !extent) {
                extent = e;
                sizer = &n;
            }
        } catch (const std::exception& e) {
            fail(n, e);
        }
    }
    Extent ext = extent.value_or(m.defaultExtent.width > 0 ? m.defaultExtent : m.extent);
    if (ext.width <= 0 || ext.height <= 0)
        throw Error("frame " + std::to_string(frameNumber) +
                    ": no pass reports a frame size and no default size was given");
    if (ext != m.extent) {
        const Extent prev = m.extent;
        if (m.frames > 0)
            spdlog::warn("frame {}: resolution changed from {}x{} to {}x{}; history reset",
                         frameNumber, m.extent.width, m.extent.height, ext.width, ext.height);
        try {
            m.allocate(ext);
        } catch (const std::bad_alloc&) {
            const std::string files = sizer ? filesOf(*sizer, frameNumber) : "";
            m.extent = Extent{};  // partly allocated: the next run of a frame starts over
            m.historyValid = m.hasPrevScene = false;
            throw Error("frame " + std::to_string(frameNumber) + ": out of memory allocating the " +
                        "planes of a " + sizeText(ext) + " frame" +
                        (m.frames > 0 ? " (the previous was " + sizeText(prev) + ")" : "") +
                        (files.empty() ? "" : ", the size " + files + " declares") +
                        ": is its data window right?");
        }
    }
    ctx.extent = ext;
    ctx.historyValid = m.historyValid;
    m.bind();

    const size_t count = m.g.order.size();
    m.times.resize(count);
    auto frameStart = Clock::now();
    std::vector<Pass*> fusedPasses;
    std::vector<PassIO*> fusedIO;
    for (size_t k0 = 0, k1 = 0; k0 < count; k0 = k1) {
        k1 = k0 + 1;  // [k0, k1): one step (fused passes share it)
        while (k1 < count && m.g.stepOf[k1] == m.g.stepOf[k0]) ++k1;
        auto& n = m.g.nodes[size_t(m.g.order[k0])];
        auto t0 = Clock::now();
        try {
            if (k1 == k0 + 1) {
                n.pass->execute(ctx, m.io[k0]);
            } else {
                fusedPasses.clear();
                fusedIO.clear();
                for (size_t k = k0; k < k1; ++k) {
                    fusedPasses.push_back(m.g.nodes[size_t(m.g.order[k])].pass.get());
                    fusedIO.push_back(&m.io[k]);
                }
                n.pass->executeFused(ctx, fusedPasses, fusedIO);
            }
        } catch (const std::exception& e) {
            std::string others;
            for (size_t k = k0 + 1; k < k1; ++k)
                others +=
                    (others.empty() ? "'" : ", '") + m.g.nodes[size_t(m.g.order[k])].name + "'";
            fail(n, e, others);
        }
        // A fused step's time is shared equally by its passes.
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        for (size_t k = k0; k < k1; ++k)
            m.times[k] = {m.g.nodes[size_t(m.g.order[k])].name, ms / double(k1 - k0)};
    }
    m.frameMs = std::chrono::duration<double, std::milli>(Clock::now() - frameStart).count();
    // Swap, not copy: this frame's buffers become next frame's history.
    m.current = 1 - m.current;
    m.historyValid = true;
    m.sceneCur = 1 - m.sceneCur;
    m.hasPrevScene = true;
    ++m.frames;
}

void Executor::resetHistory() {
    impl_->historyValid = false;
    impl_->hasPrevScene = false;
}

void Executor::endRun() {
    for (int v : impl_->g.order) impl_->g.nodes[size_t(v)].pass->endRun();
}

const std::vector<PassTime>& Executor::lastTimes() const {
    return impl_->times;
}
double Executor::lastFrameMs() const {
    return impl_->frameMs;
}
const MemoryStats& Executor::memory() const {
    return impl_->memory;
}
Extent Executor::extent() const {
    return impl_->extent;
}
int64_t Executor::framesRun() const {
    return impl_->frames;
}

ImageView Executor::output(std::string_view passPort) const {
    const auto& g = impl_->g;
    for (size_t i = 0; i < g.markedNames.size(); ++i)
        if (g.markedNames[i] == passPort) {
            int r = g.markedResource[i];
            const auto& res = g.resources[size_t(r)];
            // Before the first frame no buffer exists: indexing them would read out of bounds.
            if (impl_->extent.pixels() == 0)
                throw Error("output '" + std::string(passPort) + "' read before any frame ran");
            // After the swap the frame just written is the "previous" history buffer.
            return impl_->viewOf(r, res.history);
        }
    throw Error("'" + std::string(passPort) + "' is not a marked output of graph '" + g.desc.name +
                "' (add it to \"outputs\")");
}

}  // namespace kestrel
