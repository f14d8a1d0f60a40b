// The sequence runner on tiny test passes: which frames run and which are written (warm-up,
// resume), what a bad frame does (fail, or skip with the history reset), a stop request, and
// the observer's hooks. A recording sink and a counter with history make each visible.
#include <gtest/gtest.h>
#include <kestrel/SequenceRunner.h>

#include <set>
#include <stdexcept>

#include "../engine/TestPasses.h"

namespace kestrel::enginetest {
namespace {

/// What the test passes saw, reset by each test.
struct Seen {
    std::vector<int64_t> ran, written;  ///< frames the sink executed / wrote
    std::set<int64_t> onDisk;           ///< frames frameWritten() reports complete
    int beginRuns = 0, endRuns = 0;
};
Seen seen;

/// A source listing frames first..last; frame `bad` is missing (FrameError).
class ListedSourcePass : public Pass {
public:
    static PassDesc describe() {
        return PassDesc("ListedSource", "frame number; lists its frames; one may be missing")
            .output("out", Format::Float, "the frame number")
            .paramInt("first", 1, 0, 1000, "first frame listed")
            .paramInt("last", 0, -1, 1000, "last frame listed (before first: lists none)")
            .paramInt("bad", -1, -1, 1000, "a missing frame");
    }
    explicit ListedSourcePass(const ParamValues& p)
        : first_(p.getInt("first")), last_(p.getInt("last")), bad_(p.getInt("bad")) {}
    std::vector<int64_t> availableFrames() const override {
        std::vector<int64_t> f;
        for (int64_t i = first_; i <= last_; ++i) f.push_back(i);
        return f;
    }
    std::optional<Extent> beginFrame(FrameContext& ctx) override {
        if (ctx.frameNumber == bad_) throw FrameError("src" + std::to_string(bad_) + ".exr");
        return Extent{2, 2};
    }
    void execute(FrameContext& ctx, PassIO& io) override {
        const ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = float(ctx.frameNumber);
    }

private:
    int64_t first_, last_, bad_;
};

/// A writer recording every frame it runs and writes; reports `seen.onDisk` as written.
class RecordSinkPass : public Pass {
public:
    static PassDesc describe() {
        PassDesc d("RecordSink", "records the frames it writes");
        d.input("in", Format::Float, "input");
        d.paramBool("failBegin", false, "beginRun throws");
        d.sink = true;
        return d;
    }
    explicit RecordSinkPass(const ParamValues& p) : failBegin_(p.getBool("failBegin")) {}
    void beginRun(const RunContext&) override {
        ++seen.beginRuns;
        if (failBegin_) throw Error("cannot open out/");
    }
    void execute(FrameContext& ctx, PassIO& io) override {
        (void)io.input("in");
        seen.ran.push_back(ctx.frameNumber);
        if (ctx.writeOutputs) seen.written.push_back(ctx.frameNumber);
    }
    bool frameWritten(int64_t frame, const std::string&) const override { return seen.onDisk.count(frame) > 0; }
    void endRun() override { ++seen.endRuns; }

private:
    bool failBegin_;
};

Registry runnerRegistry() {
    Registry r = testRegistry();
    r.add<ListedSourcePass>();
    r.add<RecordSinkPass>();
    return r;
}

/// src -> sink, and a counter of frames since history became valid (marked: read per frame).
std::unique_ptr<CompiledGraph> graphWith(const Registry& r, const std::string& srcParams,
                                         const std::string& sinkParams = "{}") {
    return compileText(R"({"kestrel": 1, "name": "seq", "passes": [
        {"name": "src", "type": "ListedSource", "params": )" +
                           srcParams + R"(},
        {"name": "sink", "type": "RecordSink", "params": )" +
                           sinkParams + R"(},
        {"name": "count", "type": "Counter"}],
        "edges": [{"from": "src.out", "to": "sink.in"},
                  {"from": "count.out", "to": "count.prev", "history": true}],
        "outputs": ["count.out"]})",
                       r);
}

/// Records the observer's calls: frame -> counter value, and the skips.
struct Recorder : SequenceObserver {
    SequencePlan plan;
    std::vector<std::pair<int64_t, float>> counts;
    std::vector<size_t> indices;
    std::vector<SkippedFrame> skipped;
    int throwAt = -1;  ///< frameDone throws at this frame

    void starting(const SequencePlan& p) override { plan = p; }
    void frameDone(const FrameRecord& f, size_t index, const Executor& exec) override {
        counts.push_back({f.frame, exec.output("count.out").at(0, 0, 0)});
        indices.push_back(index);
        if (f.frame == throwAt) throw std::runtime_error("observer failed");
    }
    void frameSkipped(const SkippedFrame& s) override { skipped.push_back(s); }
};

std::vector<int64_t> framesOf(const SequenceResult& r) {
    std::vector<int64_t> f;
    for (const auto& rec : r.frames) f.push_back(rec.frame);
    return f;
}

class SequenceRunnerTest : public ::testing::Test {
protected:
    void SetUp() override { seen = {}; }
    Registry reg = runnerRegistry();
    Parallel par{1};
};

using V = std::vector<int64_t>;

TEST_F(SequenceRunnerTest, WarmupFramesRunAtTheRangeStepWithoutWriting) {
    auto g = graphWith(reg, R"({"last": 20})");
    SequenceOptions o;
    o.frames = {10, 12, 14};
    o.warmup = 2;
    SequenceRunner runner(*g, o);
    const auto& s = runner.plan().schedule;
    ASSERT_EQ(s.size(), 5u);
    EXPECT_EQ(s[0].frame, 6);
    EXPECT_FALSE(s[0].write);
    EXPECT_EQ(s[1].frame, 8);
    EXPECT_FALSE(s[1].write);
    EXPECT_TRUE(s[2].write);

    Executor exec(*g, par);
    Recorder rec;
    const SequenceResult r = runner.run(exec, &rec);
    EXPECT_EQ(r.end, SequenceEnd::Completed);
    EXPECT_EQ(seen.ran, (V{6, 8, 10, 12, 14}));
    EXPECT_EQ(seen.written, (V{10, 12, 14}));
    EXPECT_EQ(r.written(), 3u);
    EXPECT_EQ(framesOf(r), (V{6, 8, 10, 12, 14}));
    EXPECT_FALSE(r.frames[1].written);
    EXPECT_TRUE(r.frames[2].written);
    // History runs through the warm-up: the first written frame is the third with history.
    EXPECT_EQ(rec.counts[2], (std::pair<int64_t, float>{10, 3.f}));
    EXPECT_EQ(rec.indices, (std::vector<size_t>{0, 1, 2, 3, 4}));
    // Per-frame timings name every executed pass.
    ASSERT_EQ(r.frames[0].passes.size(), 3u);
    for (const auto& f : r.frames) EXPECT_GE(f.ms, 0.0);
    EXPECT_EQ(seen.beginRuns, 1);
    EXPECT_EQ(seen.endRuns, 1);
}

TEST_F(SequenceRunnerTest, FramesDefaultToWhatTheSourcesList) {
    auto g = graphWith(reg, R"({"first": 3, "last": 5})");
    SequenceRunner runner(*g, {});
    EXPECT_EQ(runner.plan().frames, (V{3, 4, 5}));
    Executor exec(*g, par);
    EXPECT_EQ(framesOf(runner.run(exec)), (V{3, 4, 5}));

    auto none = graphWith(reg, R"({"first": 1, "last": 0})");
    EXPECT_THROW(SequenceRunner(*none, {}), Error);
}

TEST_F(SequenceRunnerTest, ResumeSkipsCompleteFramesAndReplaysHistoryBeforeTheFirstMissing) {
    auto g = graphWith(reg, R"({"last": 8})");
    seen.onDisk = {1, 2, 3, 4, 6};  // 5 is missing; 6 comes after the gap and is rewritten
    SequenceOptions o;
    o.frames = {1, 2, 3, 4, 5, 6};
    o.resume = true;
    o.resumeHistory = 2;
    SequenceRunner runner(*g, o);
    EXPECT_EQ(runner.plan().schedule.size(), 6u) << "plan() is the schedule before resume";
    Executor exec(*g, par);
    Recorder rec;
    const SequenceResult r = runner.run(exec, &rec);
    EXPECT_EQ(rec.plan.alreadyWritten, 4u);
    EXPECT_EQ(rec.plan.replayed, 2u);
    EXPECT_FALSE(rec.plan.everythingWritten);
    EXPECT_EQ(seen.ran, (V{3, 4, 5, 6}));
    EXPECT_EQ(seen.written, (V{5, 6}));
    EXPECT_EQ(rec.counts[2], (std::pair<int64_t, float>{5, 3.f})) << "history of 3 and 4";

    // Warm-up frames count as history to replay: at least `warmup` frames.
    seen = {};
    seen.onDisk = {1, 2, 3, 4};
    o.warmup = 3;
    SequenceRunner warm(*g, o);
    Executor exec2(*g, par);
    warm.run(exec2);
    EXPECT_EQ(seen.ran, (V{2, 3, 4, 5, 6}));
    EXPECT_EQ(seen.written, (V{5, 6}));
}

TEST_F(SequenceRunnerTest, ResumeWithEveryFrameWrittenRunsNothing) {
    auto g = graphWith(reg, R"({"last": 8})");
    seen.onDisk = {1, 2, 3};
    SequenceOptions o;
    o.frames = {1, 2, 3};
    o.resume = true;
    SequenceRunner runner(*g, o);
    Executor exec(*g, par);
    Recorder rec;
    const SequenceResult r = runner.run(exec, &rec);
    EXPECT_TRUE(rec.plan.everythingWritten);
    EXPECT_EQ(rec.plan.alreadyWritten, 3u);
    EXPECT_EQ(r.end, SequenceEnd::Completed);
    EXPECT_TRUE(r.frames.empty());
    EXPECT_TRUE(seen.ran.empty());
}

TEST_F(SequenceRunnerTest, BadFrameFailsTheRunNamingTheFrame) {
    auto g = graphWith(reg, R"({"last": 8, "bad": 3})");
    SequenceOptions o;
    o.frames = {1, 2, 3, 4, 5};
    SequenceRunner runner(*g, o);
    Executor exec(*g, par);
    const SequenceResult r = runner.run(exec);
    EXPECT_EQ(r.end, SequenceEnd::Failed);
    EXPECT_NE(r.error.find("frame 3"), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("src3.exr"), std::string::npos) << r.error;
    EXPECT_TRUE(r.frameError) << "a missing input fails the run as a FrameError";
    EXPECT_EQ(r.lastFrame, 3);
    EXPECT_EQ(framesOf(r), (V{1, 2}));
    EXPECT_EQ(seen.written, (V{1, 2}));
    EXPECT_EQ(seen.endRuns, 1) << "endRun after a failed frame";
}

TEST_F(SequenceRunnerTest, SkipBadFramesSkipsAndResetsHistory) {
    auto g = graphWith(reg, R"({"last": 8, "bad": 3})");
    SequenceOptions o;
    o.frames = {1, 2, 3, 4, 5};
    o.skipBadFrames = true;
    SequenceRunner runner(*g, o);
    Executor exec(*g, par);
    Recorder rec;
    const SequenceResult r = runner.run(exec, &rec);
    EXPECT_EQ(r.end, SequenceEnd::Completed);
    ASSERT_EQ(r.skipped.size(), 1u);
    EXPECT_EQ(r.skipped[0].frame, 3);
    EXPECT_NE(r.skipped[0].error.find("src3.exr"), std::string::npos);
    ASSERT_EQ(rec.skipped.size(), 1u);
    EXPECT_EQ(seen.written, (V{1, 2, 4, 5}));
    using P = std::pair<int64_t, float>;
    EXPECT_EQ(rec.counts, (std::vector<P>{{1, 1.f}, {2, 2.f}, {4, 1.f}, {5, 2.f}}));
    EXPECT_EQ(rec.indices, (std::vector<size_t>{0, 1, 3, 4}));
}

TEST_F(SequenceRunnerTest, StopEndsTheRunAfterTheFrameInProgress) {
    auto g = graphWith(reg, R"({"last": 8})");
    SequenceOptions o;
    o.frames = {1, 2, 3, 4, 5};
    int polls = 0;
    o.stop = [&] { return ++polls == 2; };
    SequenceRunner runner(*g, o);
    Executor exec(*g, par);
    const SequenceResult r = runner.run(exec);
    EXPECT_EQ(r.end, SequenceEnd::Stopped);
    EXPECT_EQ(framesOf(r), (V{1, 2}));
    EXPECT_EQ(r.lastFrame, 2);
    EXPECT_EQ(seen.written, (V{1, 2}));
    EXPECT_EQ(seen.endRuns, 1);
}

TEST_F(SequenceRunnerTest, BeginRunFailureRunsNoFrame) {
    auto g = graphWith(reg, R"({"last": 8})", R"({"failBegin": true})");
    SequenceOptions o;
    o.frames = {1, 2};
    SequenceRunner runner(*g, o);
    Executor exec(*g, par);
    const SequenceResult r = runner.run(exec);
    EXPECT_EQ(r.end, SequenceEnd::Failed);
    EXPECT_NE(r.error.find("cannot open out/"), std::string::npos) << r.error;
    EXPECT_FALSE(r.frameError);
    EXPECT_TRUE(r.frames.empty());
    EXPECT_TRUE(seen.ran.empty());
}

TEST_F(SequenceRunnerTest, ObserverExceptionLeavesRunAfterEndRun) {
    auto g = graphWith(reg, R"({"last": 8})");
    SequenceOptions o;
    o.frames = {1, 2, 3};
    SequenceRunner runner(*g, o);
    Executor exec(*g, par);
    Recorder rec;
    rec.throwAt = 2;
    EXPECT_THROW(runner.run(exec, &rec), std::runtime_error);
    EXPECT_EQ(seen.ran, (V{1, 2}));
    EXPECT_EQ(seen.endRuns, 1);
}

TEST_F(SequenceRunnerTest, WriteOutputsFalseWritesNothing) {
    auto g = graphWith(reg, R"({"last": 8})");
    SequenceOptions o;
    o.frames = {1, 2};
    o.writeOutputs = false;
    SequenceRunner runner(*g, o);
    Executor exec(*g, par);
    const SequenceResult r = runner.run(exec);
    EXPECT_EQ(seen.ran, (V{1, 2}));
    EXPECT_TRUE(seen.written.empty());
    EXPECT_EQ(r.written(), 0u);
}

}  // namespace
}  // namespace kestrel::enginetest
