// Compiler phase 8: the resource plan: lifetimes, transient planes aliased by lifetime, history
// buffers and the idle memory they lend.
#include "Compiler.h"

namespace kestrel::compiler {

namespace {

/// History memory lent to transient resources while it is idle (CompileOptions::historyIdle):
/// last frame's value is dead once its last reader has run, until this frame's is written over
/// it (one buffer) or to the end of the frame (two buffers: this frame's is in the other).
class IdleHistory {
public:
    IdleHistory(const std::vector<ResourceInfo>& resources, int end) {
        for (size_t h = 0; h < resources.size(); ++h) {
            const ResourceInfo& r = resources[h];
            if (!r.history) continue;
            const int until = r.doubleBuffered ? end : r.firstUse;
            for (int c = 0; c < channelCount(r.format); ++c)
                planes_.push_back({{int(h), c}, r.lastHistoryRead + 1, until});
        }
    }

    /// `count` planes idle through steps [first, last], now taken; none if there are fewer.
    std::vector<HistoryPlane> take(int count, int first, int last) {
        std::vector<Slot*> found;
        for (Slot& s : planes_)
            if (int(found.size()) < count && s.from <= first && last < s.until &&
                s.busyUntil < first)
                found.push_back(&s);
        return claim(found, count, last);
    }

    /// Every plane of the one-buffer history resource `h`, idle from step `first` until its
    /// producer writes it, now taken: that pass writes it in place of the resource taking them.
    std::vector<HistoryPlane> takeWhole(int h, int first) {
        std::vector<Slot*> found;
        int count = 0;
        for (Slot& s : planes_)
            if (s.plane.resource == h) {
                ++count;
                if (s.from <= first && s.busyUntil < first) found.push_back(&s);
            }
        return claim(found, count, found.empty() ? 0 : found.front()->until);
    }

private:
    struct Slot {
        HistoryPlane plane;
        int from, until;     // idle in steps [from, until)
        int busyUntil = -1;  // last step of the resource holding it
    };
    static std::vector<HistoryPlane> claim(const std::vector<Slot*>& found, int count, int last) {
        if (count == 0 || int(found.size()) < count) return {};
        std::vector<HistoryPlane> out;
        for (Slot* s : found) {
            s->busyUntil = last;
            out.push_back(s->plane);
        }
        return out;
    }
    std::vector<Slot> planes_;
};

}  // namespace

void Compiler::planResources() {
    // Indices are steps: passes fused into one step read and write at the same time.
    std::vector<int> execIndex(g_->nodes.size(), -1);
    for (size_t k = 0; k < g_->order.size(); ++k) execIndex[size_t(g_->order[k])] = g_->stepOf[k];
    const int end = g_->steps;
    std::map<std::pair<int, int>, int> resourceOf;  // (node, output port) -> resource
    std::vector<int> producerNode;                  // resource -> node
    auto getResource = [&](PortRef src) {
        auto key = std::make_pair(src.node, src.port);
        auto it = resourceOf.find(key);
        if (it != resourceOf.end()) return it->second;
        const PortDesc& pd = descOf(src.node).ports[size_t(src.port)];
        if (pd.format == Format::Any)
            throw Error("pass '" + node(src.node).name + "' output '" + pd.name +
                        "' has format any and must be forwarded");
        ResourceInfo r;
        r.producer = portName(src);
        r.format = pd.format;
        r.firstUse = r.lastUse = execIndex[size_t(src.node)];
        int id = int(g_->resources.size());
        g_->resources.push_back(r);
        producerNode.push_back(src.node);
        resourceOf[key] = id;
        node(src.node).portResource[size_t(src.port)] = id;
        return id;
    };
    for (int v : g_->order) {
        const auto& ports = descOf(v).ports;
        for (size_t p = 0; p < ports.size(); ++p) {
            if (ports[p].kind != PortKind::Input) continue;
            auto src = sourceOf(v, int(p));
            if (!src || execIndex[size_t(src->node)] < 0) continue;
            int r = getResource(*src);
            bool hist = edge(node(v).inEdge[p]).history;
            node(v).portResource[p] = r;
            node(v).portHistory[p] = hist;
            auto& res = g_->resources[size_t(r)];
            if (hist) {
                res.history = true;
                res.lastHistoryRead = std::max(res.lastHistoryRead, execIndex[size_t(v)]);
            } else
                res.lastUse = std::max(res.lastUse, execIndex[size_t(v)]);
        }
    }
    for (auto& res : g_->resources)
        res.doubleBuffered = res.history && res.lastHistoryRead >= res.firstUse;
    g_->markedResource.clear();
    for (auto [v, p] : g_->marked) {
        int r = getResource({v, p});
        g_->resources[size_t(r)].marked = true;
        g_->resources[size_t(r)].lastUse = end;
        g_->markedResource.push_back(r);
    }
    // Lifetime-based aliasing: walk the execution order, give each transient output the
    // lowest free planes before its pass runs, and free a resource's planes once its last
    // reader has run. Outputs are taken before inputs are freed, so a pass never writes
    // into memory it reads, except in place: an output declared inPlaceOf an input takes
    // over that input's planes when this pass is the input's last reader (the pass is
    // pointwise on the pair). History resources persist across frames; their memory is lent
    // only while idle (IdleHistory).
    std::vector<bool> handedOver(g_->resources.size(), false);
    std::vector<int> stepSize(size_t(end), 0);
    for (int step : g_->stepOf) ++stepSize[size_t(step)];
    // The resource that output resource `r` may be written over (PassDesc::inPlaceOf):
    // the declared input, read this frame through that port only, by a pass in a step of
    // its own (in a fused step the passes run at once, so any may still read it); else -1.
    auto inPlaceInput = [&](int r) -> int {
        const int v = producerNode[size_t(r)];
        if (!options_.inPlace || stepSize[size_t(g_->resources[size_t(r)].firstUse)] != 1)
            return -1;
        const auto& ports = descOf(v).ports;
        const auto& pr = node(v).portResource;
        int out = -1;
        for (size_t p = 0; p < ports.size(); ++p)
            if (ports[p].kind == PortKind::Output && pr[p] == r) out = int(p);
        if (out < 0 || ports[size_t(out)].inPlaceOf.empty()) return -1;
        int in = -1, readers = 0;
        for (size_t p = 0; p < ports.size(); ++p)
            if (ports[p].kind == PortKind::Input && ports[p].name == ports[size_t(out)].inPlaceOf)
                in = int(p);
        if (in < 0 || pr[size_t(in)] < 0 || node(v).portHistory[size_t(in)]) return -1;
        const int src = pr[size_t(in)];
        for (size_t p = 0; p < ports.size(); ++p)  // read through this port only
            if (ports[p].kind == PortKind::Input && pr[p] == src) ++readers;
        const auto& s = g_->resources[size_t(src)];
        if (readers != 1 || s.history || s.marked || s.format != g_->resources[size_t(r)].format)
            return -1;
        return src;
    };
    // Transient output r takes over its input's planes when r's pass is the input's last
    // reader and the input holds planes of its own.
    auto inPlaceSource = [&](int k, int r) -> int {
        const int src = inPlaceInput(r);
        if (src < 0) return -1;
        const auto& s = g_->resources[size_t(src)];
        if (s.lastUse != k || !s.historyPlanes.empty() || handedOver[size_t(src)]) return -1;
        return src;
    };
    // A one-buffer history resource written over a transient resource in place (its last
    // reader there) can hold that resource from its first step, when last frame's value is
    // read by then: e.g. the accumulated colour that a blend turns into next frame's
    // history. writtenOver[r]: that history, else -1.
    IdleHistory idleHistory(g_->resources, end);
    const bool lend = options_.historyIdle;
    std::vector<int> writtenOver(g_->resources.size(), -1);
    for (size_t h = 0; h < g_->resources.size() && lend; ++h) {
        const auto& hist = g_->resources[h];
        if (!hist.history || hist.doubleBuffered) continue;
        if (const int src = inPlaceInput(int(h));
            src >= 0 && g_->resources[size_t(src)].lastUse == hist.firstUse)
            writtenOver[size_t(src)] = int(h);
    }
    std::set<int> freePlanes;
    int nextPlane = 0;
    // Idle while step k runs: free after its outputs are placed, before its inputs are
    // released (it still reads them), plus every plane first taken after step k.
    std::vector<std::vector<int>> idle(static_cast<size_t>(end));
    std::vector<int> firstUnused(static_cast<size_t>(end));
    for (int k = 0; k < end; ++k) {
        for (size_t r = 0; r < g_->resources.size(); ++r) {
            auto& res = g_->resources[r];
            if (res.history || res.firstUse != k) continue;
            int need = channelCount(res.format);
            g_->unaliasedPlanes += need;
            if (writtenOver[r] >= 0) {
                res.historyPlanes = idleHistory.takeWhole(writtenOver[r], k);
                if (!res.historyPlanes.empty()) continue;
            }
            if (const int src = inPlaceSource(k, int(r)); src >= 0) {
                res.planes = g_->resources[size_t(src)].planes;
                res.inPlaceOf = src;
                handedOver[size_t(src)] = true;
                continue;
            }
            if (lend && !res.marked) {
                res.historyPlanes = idleHistory.take(need, k, res.lastUse);
                if (!res.historyPlanes.empty()) continue;
            }
            for (int c = 0; c < need; ++c) {
                if (!freePlanes.empty()) {
                    res.planes.push_back(*freePlanes.begin());
                    freePlanes.erase(freePlanes.begin());
                } else {
                    res.planes.push_back(nextPlane++);
                }
            }
        }
        idle[size_t(k)].assign(freePlanes.begin(), freePlanes.end());
        firstUnused[size_t(k)] = nextPlane;
        for (size_t r = 0; r < g_->resources.size(); ++r) {
            const auto& res = g_->resources[r];
            if (!res.history && res.historyPlanes.empty() && res.lastUse == k && !handedOver[r])
                for (int pl : res.planes) freePlanes.insert(pl);
        }
    }
    g_->transientPlanes = nextPlane;
    for (int k = 0; k < end; ++k)
        for (int pl = firstUnused[size_t(k)]; pl < nextPlane; ++pl) idle[size_t(k)].push_back(pl);
    g_->idlePlanes = std::move(idle);
}

}  // namespace kestrel::compiler
