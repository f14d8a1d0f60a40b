#pragma once
// Tiny test-only passes for the engine suite, registered straight into a kestrel::Registry.
// Every pass works on Float images so values are easy to predict; passes that must never run
// throw from execute(), so a scheduling bug fails the test instead of going unnoticed.
#include <kestrel/Compiler.h>
#include <kestrel/Executor.h>
#include <kestrel/Graph.h>
#include <kestrel/Kestrel.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace kestrel::enginetest {

/// Writes a constant.
class ConstPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Const", "constant image")
            .output("out", Format::Float, "the constant")
            .paramFloat("value", 1.0, -1e6, 1e6, "value written");
    }
    explicit ConstPass(const ParamValues& p) : value_(p.getFloat("value")) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = value_;
    }

private:
    float value_;
};

/// Writes x + 10 y: a non-constant source, so in-place corruption changes values.
class RampPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Ramp", "x + 10 y").output("out", Format::Float, "the ramp");
    }
    explicit RampPass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& o = io.output("out");
        for (int y = 0; y < o.height(); ++y)
            for (int x = 0; x < o.width(); ++x) o.at(0, x, y) = float(x + 10 * y);
    }
};

/// Writes the frame number; reports its frame size through beginFrame: width x height, or
/// width2 x height from frame `switchAt` on (a resolution change mid-sequence).
class FrameNumberPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("FrameNumber", "frame number; a source with a frame size")
            .output("out", Format::Float, "the frame number")
            .paramInt("width", 2, 1, 4096, "frame width")
            .paramInt("height", 2, 1, 4096, "frame height")
            .paramInt("width2", 2, 1, 4096, "frame width from frame switchAt on")
            .paramInt("switchAt", 1000000, 0, 1000000, "first frame of width2");
    }
    explicit FrameNumberPass(const ParamValues& p)
        : w_(int(p.getInt("width"))),
          h_(int(p.getInt("height"))),
          w2_(int(p.getInt("width2"))),
          switchAt_(p.getInt("switchAt")) {}
    std::optional<Extent> beginFrame(FrameContext& ctx) override {
        return Extent{ctx.frameNumber >= switchAt_ ? w2_ : w_, h_};
    }
    void execute(FrameContext& ctx, PassIO& io) override {
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = float(ctx.frameNumber);
    }

private:
    int w_, h_, w2_;
    int64_t switchAt_;
};

/// out = in + 1. Carries one parameter of every type for the validation tests.
class AddOnePass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("AddOne", "in + 1")
            .input("in", Format::Float, "input")
            .output("out", Format::Float, "in + 1")
            .paramFloat("alpha", 0.5, 0.0, 1.0, "unused weight")
            .paramInt("count", 1, 1, 10, "unused count")
            .paramBool("enabled", true, "unused flag")
            .paramEnum("mode", "box", {"box", "gauss"}, "unused choice")
            .paramEnum("tristate", "auto", {"auto", "true", "false"}, "unused three-way choice");
    }
    explicit AddOnePass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& in = io.input("in");
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = in.channel(0)[i] + 1.f;
    }
};

/// AddOne, after filling every idle plane it is lent (PassIO::idlePlanes) with NaN: a plane
/// wrongly counted idle corrupts a resource some pass still reads. Counts the planes.
class ScribbleIdlePass : public AddOnePass {
public:
    static PassDesc describe() {
        return PassDesc("ScribbleIdle", "in + 1, with NaN in every idle plane")
            .input("in", Format::Float, "input")
            .output("out", Format::Float, "in + 1");
    }
    using AddOnePass::AddOnePass;
    void execute(FrameContext& ctx, PassIO& io) override {
        lastIdleCount = io.idlePlanes().size();
        for (float* plane : io.idlePlanes())
            std::fill(plane, plane + ctx.extent.pixels(), std::numeric_limits<float>::quiet_NaN());
        AddOnePass::execute(ctx, io);
    }
    static inline size_t lastIdleCount = 0;
};

/// out = 2 in + 1 (+ other when bound), pointwise, declared in place of `in`: the compiler may
/// give `out` the memory of `in`. Records whether it last ran in place (both views on the same
/// planes).
class ScaleInPlacePass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("ScaleInPlace", "2 in + 1 (+ other), pointwise")
            .input("in", Format::Float, "input")
            .optionalInput("other", Format::Float, "added when bound")
            .output("out", Format::Float, "2 in + 1 (+ other)")
            .inPlaceOf("in");
    }
    explicit ScaleInPlacePass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& in = io.input("in");
        const float* other = io.hasInput("other") ? io.input("other").channel(0) : nullptr;
        const ImageView& o = io.output("out");
        lastRunInPlace = in.channel(0) == o.channel(0);
        for (size_t i = 0; i < o.pixels(); ++i)
            o.channel(0)[i] = 2.f * in.channel(0)[i] + 1.f + (other ? other[i] : 0.f);
    }
    static inline bool lastRunInPlace = false;
};

/// out(x) = (in(x) + in(x-1)) / 2 along each row. Reading the left neighbour after writing the
/// current pixel means in-place (aliased) execution gives different values; aliasing of its own
/// input and output is also reported as an error outright.
class NeighbourAveragePass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("NeighbourAverage", "average with left neighbour")
            .input("in", Format::Float, "input")
            .output("out", Format::Float, "averaged");
    }
    explicit NeighbourAveragePass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& in = io.input("in");
        const ImageView& o = io.output("out");
        if (in.channel(0) == o.channel(0)) throw Error("output aliases input");
        for (int y = 0; y < o.height(); ++y) {
            const float* src = in.row(0, y);
            float* dst = o.row(0, y);
            dst[0] = src[0];
            for (int x = 1; x < o.width(); ++x) dst[x] = 0.5f * (src[x] + src[x - 1]);
        }
    }
};

/// out = a + b.
class SumPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Sum", "a + b")
            .input("a", Format::Float, "first")
            .input("b", Format::Float, "second")
            .output("out", Format::Float, "a + b");
    }
    explicit SumPass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& a = io.input("a");
        const ImageView& b = io.input("b");
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = a.channel(0)[i] + b.channel(0)[i];
    }
};

/// Reads its own previous output through a history edge: out = prev + 1, or 1 when the
/// history is invalid. Throws if io.historyValid and ctx.historyValid disagree.
class CounterPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Counter", "frames since the history became valid")
            .historyInput("prev", Format::Float, "last frame's count")
            .output("out", Format::Float, "count");
    }
    explicit CounterPass(const ParamValues&) {}
    void execute(FrameContext& ctx, PassIO& io) override {
        bool valid = io.historyValid("prev");
        if (valid != ctx.historyValid) throw Error("io.historyValid disagrees with ctx");
        if (valid != io.hasInput("prev")) throw Error("hasInput disagrees with historyValid");
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i)
            o.channel(0)[i] = valid ? io.input("prev").channel(0)[i] + 1.f : 1.f;
    }
};

/// out = last frame's `prev`, or -1 when the history is invalid.
class PreviousPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Previous", "last frame's value of its history input")
            .historyInput("prev", Format::Float, "last frame's value")
            .output("out", Format::Float, "prev or -1");
    }
    explicit PreviousPass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& o = io.output("out");
        bool valid = io.historyValid("prev");
        for (size_t i = 0; i < o.pixels(); ++i)
            o.channel(0)[i] = valid ? io.input("prev").channel(0)[i] : -1.f;
    }
};

/// out = 2 opt when the optional input is bound, else 7.
class OptionalUserPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("OptionalUser", "adapts to an optional input")
            .optionalInput("opt", Format::Float, "optional")
            .output("out", Format::Float, "2 opt or 7");
    }
    explicit OptionalUserPass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& o = io.output("out");
        bool has = io.hasInput("opt");
        for (size_t i = 0; i < o.pixels(); ++i)
            o.channel(0)[i] = has ? 2.f * io.input("opt").channel(0)[i] : 7.f;
    }
};

/// out = first when bound (and then `second` is declared unused), else second.
class PreferFirstPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("PreferFirst", "reads first when bound, else second")
            .optionalInput("first", Format::Float, "preferred")
            .optionalInput("second", Format::Float, "fallback")
            .output("out", Format::Float, "first or second");
    }
    explicit PreferFirstPass(const ParamValues&) {}
    void resolve(ResolveContext& rc) override {
        if (rc.isBound("first")) rc.ignoreInput("second", "first is bound");
    }
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& src = io.hasInput("first") ? io.input("first") : io.input("second");
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = src.channel(0)[i];
    }
};

/// Identity for every scene: resolve() forwards out to in, so it must never execute.
class ForwardPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Forward", "identity")
            .input("in", Format::Float, "input")
            .output("out", Format::Float, "= in");
    }
    explicit ForwardPass(const ParamValues&) {}
    void resolve(ResolveContext& rc) override {
        rc.forward("out", "in");
        rc.note("nothing to do: out is in");
    }
    void execute(FrameContext&, PassIO&) override { throw Error("Forward executed"); }
};

/// A source whose scene lacks its channel: resolve() marks the output absent.
class MissingPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Missing", "absent channel").output("out", Format::Float, "never produced");
    }
    explicit MissingPass(const ParamValues&) {}
    void resolve(ResolveContext& rc) override { rc.setAbsent("out", "scene has no albedo AOV"); }
    void execute(FrameContext&, PassIO&) override { throw Error("Missing executed"); }
};

/// Pass-through that must never run (for passes the compiler has to prune).
class ExplodePass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Explode", "throws when executed")
            .input("in", Format::Float, "input")
            .output("out", Format::Float, "never written");
    }
    explicit ExplodePass(const ParamValues&) {}
    void execute(FrameContext&, PassIO&) override { throw Error("Explode executed"); }
};

/// A writer: always live.
class SinkPass : public Pass {
public:
    static PassDesc describe() {
        PassDesc d("Sink", "consumes its input");
        d.input("in", Format::Float, "input");
        d.sink = true;
        return d;
    }
    explicit SinkPass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override { (void)io.input("in"); }
};

/// A float3 producer, for format checks.
class ColorPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("Color", "float3 source").output("color", Format::Float3, "rgb");
    }
    explicit ColorPass(const ParamValues&) {}
    void execute(FrameContext&, PassIO& io) override {
        const ImageView& o = io.output("color");
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < o.pixels(); ++i) o.channel(c)[i] = float(c);
    }
};

/// A per-row recurrence with transcendentals: enough work per row that several threads
/// really interleave, and any chunking dependence would change the result.
class RowWorkPass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("RowWork", "per-row recurrence")
            .input("in", Format::Float, "input")
            .output("out", Format::Float, "filtered");
    }
    explicit RowWorkPass(const ParamValues&) {}
    void execute(FrameContext& ctx, PassIO& io) override {
        const ImageView& in = io.input("in");
        const ImageView& o = io.output("out");
        ctx.parallelRows(o.height(), [&](int y0, int y1) {
            for (int y = y0; y < y1; ++y) {
                const float* src = in.row(0, y);
                float* dst = o.row(0, y);
                float acc = 0.f;
                for (int x = 0; x < o.width(); ++x) {
                    acc = 0.9f * acc + std::sin(0.01f * src[x] + float(y)) +
                          std::exp(-0.001f * float(x));
                    dst[x] = acc;
                }
            }
        });
    }
};

/// out(x, y) = 0.5 (in(x, y) + in(x - 1, y)) + guide(x, y): reads a neighbour, so memory
/// aliased under a pass still reading corrupts it. Fusable on `guide` when `key` > 0; its
/// executeFused interleaves the members pixel by pixel (each member's pixel written before the
/// next member's is read) and counts its calls.
class GuidedPass : public Pass {
public:
    static inline int fusedCalls = 0;
    static PassDesc describe() {
        return PassDesc("Guided", "neighbour average plus a guide; fusable on the guide")
            .input("in", Format::Float, "input")
            .input("guide", Format::Float, "shared guide")
            .output("out", Format::Float, "filtered")
            .output("aux", Format::Float, "the guide, copied")
            .fuseOn({"guide"})
            .paramInt("key", 0, 0, 100, "fusion key (0: never fused)")
            .paramBool("fail", false, "throw a FrameError instead of filtering");
    }
    explicit GuidedPass(const ParamValues& p)
        : key_(int(p.getInt("key"))), fail_(p.getBool("fail")) {}
    std::string fusionKey() const override {
        return key_ > 0 ? "key=" + std::to_string(key_) : std::string();
    }
    void execute(FrameContext&, PassIO& io) override {
        if (fail_) throw FrameError("this pass fails");
        PassIO* ios[1] = {&io};
        filter(ios);
    }
    void executeFused(FrameContext&, std::span<Pass* const> passes,
                      std::span<PassIO* const> ios) override {
        ++fusedCalls;
        for (Pass* p : passes)
            if (static_cast<GuidedPass*>(p)->fail_) throw FrameError("a fused pass fails");
        filter(ios);
    }

private:
    static void filter(std::span<PassIO* const> ios) {
        const ImageView& o0 = ios[0]->output("out");
        for (int y = 0; y < o0.height(); ++y)
            for (int x = 0; x < o0.width(); ++x)
                for (PassIO* io : ios) {
                    const ImageView& in = io->input("in");
                    const float left = in.at(0, x > 0 ? x - 1 : x, y);
                    io->output("out").at(0, x, y) =
                        0.5f * (in.at(0, x, y) + left) + io->input("guide").at(0, x, y);
                    if (io->hasOutput("aux"))
                        io->output("aux").at(0, x, y) = io->input("guide").at(0, x, y);
                }
    }
    int key_;
    bool fail_;
};

/// Guided, fused also where members leave different outputs unconsumed (its filter writes `aux`
/// only where it is bound).
class GuidedAnyOutputsPass : public GuidedPass {
public:
    static PassDesc describe() {
        PassDesc d = GuidedPass::describe();
        d.type = "GuidedAnyOutputs";
        return d.fuseOn({"guide"}, PassDesc::FusedOutputs::MayDiffer);
    }
    using GuidedPass::GuidedPass;
};

inline Registry testRegistry() {
    Registry r;
    r.add<ConstPass>();
    r.add<RampPass>();
    r.add<FrameNumberPass>();
    r.add<AddOnePass>();
    r.add<ScaleInPlacePass>();
    r.add<NeighbourAveragePass>();
    r.add<SumPass>();
    r.add<CounterPass>();
    r.add<PreviousPass>();
    r.add<OptionalUserPass>();
    r.add<ForwardPass>();
    r.add<PreferFirstPass>();
    r.add<MissingPass>();
    r.add<ExplodePass>();
    r.add<SinkPass>();
    r.add<ColorPass>();
    r.add<RowWorkPass>();
    r.add<ScribbleIdlePass>();
    r.add<GuidedPass>();
    r.add<GuidedAnyOutputsPass>();
    return r;
}

/// Parses and compiles a graph against the test registry.
inline std::unique_ptr<CompiledGraph> compileText(const std::string& json, const Registry& r) {
    return compileGraph(parseGraph(json), r);
}

}  // namespace kestrel::enginetest
