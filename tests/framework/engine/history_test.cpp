// History edges over several frames: first-frame invalidity, swap (not copy), reset and
// resolution change, checked value by value through the executor's marked outputs.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

// `clock` reports the frame size (2x2, 3x2 from frame 100 on) and is marked so it stays live.
const char* kCounterGraph = R"({"kestrel": 1, "name": "counter", "passes": [
    {"name": "clock", "type": "FrameNumber", "params": {"width": 2, "height": 2, "width2": 3,
                                                        "switchAt": 100}},
    {"name": "count", "type": "Counter"}],
    "edges": [{"from": "count.out", "to": "count.prev", "history": true}],
    "outputs": ["count.out", "clock.out"]})";

/// The counter's value, checked to be the same at every pixel.
float counterValue(const Executor& ex) {
    ImageView v = ex.output("count.out");
    float first = v.at(0, 0, 0);
    for (int y = 0; y < v.height(); ++y)
        for (int x = 0; x < v.width(); ++x)
            EXPECT_EQ(v.at(0, x, y), first) << "pixel " << x << "," << y;
    return first;
}

TEST(History, CounterCountsFramesResetsAndRestartsOnResolutionChange) {
    Registry r = testRegistry();
    auto g = compileText(kCounterGraph, r);
    Parallel par(1);
    Executor ex(*g, par);

    ex.runFrame(1);
    EXPECT_EQ(counterValue(ex), 1.f) << "first frame: history invalid";
    ex.runFrame(2);
    EXPECT_EQ(counterValue(ex), 2.f);
    ex.runFrame(3);
    EXPECT_EQ(counterValue(ex), 3.f);

    ex.resetHistory();
    ex.runFrame(4);
    EXPECT_EQ(counterValue(ex), 1.f) << "after resetHistory";
    ex.runFrame(5);
    EXPECT_EQ(counterValue(ex), 2.f);

    EXPECT_EQ(ex.extent(), (Extent{2, 2}));
    ex.runFrame(100);
    EXPECT_EQ(ex.extent(), (Extent{3, 2}));
    EXPECT_EQ(counterValue(ex), 1.f) << "after a resolution change";
    ex.runFrame(101);
    EXPECT_EQ(counterValue(ex), 2.f);
    EXPECT_EQ(ex.output("clock.out").at(0, 2, 1), 101.f);
    EXPECT_EQ(ex.framesRun(), 7);
}

TEST(History, BuffersAreSwappedNotCopied) {
    Registry r = testRegistry();
    auto g = compileText(kCounterGraph, r);
    ASSERT_EQ(g->resources().size(), 2u);
    Parallel par(1);
    Executor ex(*g, par);
    // Two buffers, used alternately: frame n writes where frame n-2 wrote.
    ex.runFrame(1);
    const float* a = ex.output("count.out").channel(0);
    ex.runFrame(2);
    const float* b = ex.output("count.out").channel(0);
    ex.runFrame(3);
    const float* c = ex.output("count.out").channel(0);
    EXPECT_NE(a, b);
    EXPECT_EQ(a, c);
    // History is double-buffered and never shares memory with transients.
    EXPECT_EQ(ex.memory().historyPlanes, 2u);
    EXPECT_EQ(ex.memory().transientPlanes, 1u);  // clock.out
}

TEST(History, ReaderSeesAnotherPassesPreviousFrame) {
    Registry r = testRegistry();
    // `prev` runs before the producer `clock` (file order) and still sees last frame's value.
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "prev", "type": "Previous"},
        {"name": "clock", "type": "FrameNumber"}],
        "edges": [{"from": "clock.out", "to": "prev.prev", "history": true}],
        "outputs": ["prev.out", "clock.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (std::vector<std::string>{"prev", "clock"}));
    Parallel par(1);
    Executor ex(*g, par);
    ex.runFrame(10);
    EXPECT_EQ(ex.output("prev.out").at(0, 1, 1), -1.f);
    EXPECT_EQ(ex.output("clock.out").at(0, 1, 1), 10.f);
    ex.runFrame(11);
    EXPECT_EQ(ex.output("prev.out").at(0, 1, 1), 10.f);
    ex.runFrame(12);
    EXPECT_EQ(ex.output("prev.out").at(0, 1, 1), 11.f);
    ex.resetHistory();
    ex.runFrame(13);
    EXPECT_EQ(ex.output("prev.out").at(0, 1, 1), -1.f);
    // Its only history reader runs before the producer: one buffer, read then rewritten.
    EXPECT_EQ(ex.memory().historyPlanes, 1u);
}

TEST(History, OneBufferWhenEveryReaderRunsBeforeTheProducer) {
    Registry r = testRegistry();
    // `prev` reads last frame's clock before `clock` runs: single-buffered, and still correct
    // over frames; the counter reads its own last value while writing: two buffers.
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "prev", "type": "Previous"},
        {"name": "clock", "type": "FrameNumber"}, {"name": "count", "type": "Counter"}],
        "edges": [{"from": "clock.out", "to": "prev.prev", "history": true},
                  {"from": "count.out", "to": "count.prev", "history": true}],
        "outputs": ["prev.out", "clock.out", "count.out"]})",
                         r);
    std::map<std::string, bool> twoBuffers;
    for (const auto& res : g->resources())
        if (res.history) twoBuffers[res.producer] = res.doubleBuffered;
    EXPECT_EQ(twoBuffers, (std::map<std::string, bool>{{"clock.out", false}, {"count.out", true}}));
    Parallel par(1);
    Executor ex(*g, par);
    for (int f = 20; f < 24; ++f) {
        ex.runFrame(f);
        EXPECT_EQ(ex.output("prev.out").at(0, 0, 0), f == 20 ? -1.f : float(f - 1));
        EXPECT_EQ(ex.output("clock.out").at(0, 0, 0), float(f));
        EXPECT_EQ(ex.output("count.out").at(0, 0, 0), float(f - 19));
    }
    EXPECT_EQ(ex.memory().historyPlanes, 3u);  // clock 1 + counter 2
    ex.runFrame(30);  // a skipped frame number does not matter; only order does
    EXPECT_EQ(ex.output("prev.out").at(0, 0, 0), 23.f);
}

/// Throws on one chosen frame, after the counter has already written its output.
class FailOnFramePass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("FailOnFrame", "throws FrameError on frame 3")
            .input("in", Format::Float, "input")
            .output("out", Format::Float, "copy");
    }
    explicit FailOnFramePass(const ParamValues&) {}
    void execute(FrameContext& ctx, PassIO& io) override {
        if (ctx.frameNumber == 3) throw FrameError("frame 3 is corrupt");
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = io.input("in").channel(0)[i];
    }
};

TEST(History, AFailedFrameInvalidatesHistory) {
    Registry r = testRegistry();
    r.add<FailOnFramePass>();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "count", "type": "Counter"},
        {"name": "check", "type": "FailOnFrame"}],
        "edges": [{"from": "count.out", "to": "count.prev", "history": true},
                  {"from": "count.out", "to": "check.in"}],
        "outputs": ["check.out"]})",
                         r);
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{2, 1});
    ex.runFrame(1);
    ex.runFrame(2);
    EXPECT_EQ(ex.output("check.out").at(0, 0, 0), 2.f);
    try {
        ex.runFrame(3);
        FAIL() << "frame 3 should fail";
    } catch (const FrameError& e) {
        std::string m = e.what();
        EXPECT_NE(m.find("frame 3"), std::string::npos) << m;
        EXPECT_NE(m.find("'check'"), std::string::npos) << m;
        EXPECT_NE(m.find("frame 3 is corrupt"), std::string::npos) << m;
    }
    ex.runFrame(4);
    EXPECT_EQ(ex.output("check.out").at(0, 0, 0), 1.f) << "history must restart after a failure";
    ex.runFrame(5);
    EXPECT_EQ(ex.output("check.out").at(0, 0, 0), 2.f);
}

TEST(Executor, OutputErrors) {
    Registry r = testRegistry();
    auto g = compileText(kCounterGraph, r);
    Parallel par(1);
    Executor ex(*g, par);
    EXPECT_THROW(ex.output("count.out"), Error) << "no frame has run yet";
    ex.runFrame(1);
    try {
        ex.output("clock.nope");
        FAIL();
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("not a marked output"), std::string::npos);
    }
}

TEST(Executor, NoFrameSizeIsAnError) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "c", "type": "Const"}],
        "outputs": ["c.out"]})",
                         r);
    Parallel par(1);
    Executor ex(*g, par);
    EXPECT_THROW(ex.runFrame(1), Error);
}

}  // namespace
}  // namespace kestrel::enginetest
