// kestrel run: compile a graph and execute it frame by frame over a sequence.
#include <eval/ExrRgb.h>
#include <eval/Metrics.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <map>
#include <set>

#include "Commands.h"
#include "Common.h"
#include "Dump.h"
#include "OutputSafety.h"
#include "Progress.h"
#include "ReportSummary.h"
#include "kestrel/Executor.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Log.h"
#include "kestrel/Scratch.h"
#include "kestrel/SequenceRunner.h"

namespace kestrel::cli {

namespace fs = std::filesystem;

namespace {

// The signal that asked the run to stop (0: none). SIGTERM (Slurm's time limit, Deadline's
// cancel, `kill`) is handled as SIGINT: the frame in progress is finished, its temporary file
// renamed, and the exit code says which signal (128 + its number, as a shell reports it).
std::atomic<int> gInterrupted{0};
extern "C" void onInterrupt(int sig) {
    gInterrupted.store(sig);
}

struct RunOptions {
    GraphOptions graph;
    std::string frames;
    int threads = 0;
    bool resume = false;
    int warmup = 0;
    bool skipBadFrames = false;
    bool noFuse = false;
    std::string size;                 // WxH for graphs without a source
    std::string reference, refLayer;  // print each frame's error against these frames
    std::vector<std::string> dumps;   // --dump patterns
    std::string dumpDir;
    std::string cuts;               // --cuts: frames where history is reset (camera cuts)
    std::string progress = "auto";  // --progress: auto (bar or log lines), openjd
};

void logReport(const CompiledGraph& g) {
    const auto& r = g.report();
    if (spdlog::should_log(spdlog::level::debug)) {  // -v: every note and left-out pass
        for (const auto& n : r.notes) spdlog::debug("scene: {}", n);
        for (const auto& p : r.elided) spdlog::debug("left out {}: {}", p.pass, p.reason);
        for (const auto& f : r.fused) {
            std::string names;
            for (const auto& name : f) names += (names.empty() ? "" : " + ") + name;
            spdlog::debug("fused: {}", names);
        }
        for (const auto& p : r.pruned) spdlog::debug("pruned {}: {}", p.pass, p.reason);
        for (const auto& a : r.absent) spdlog::debug("absent {}", a);
    } else {
        for (const auto& line : groupNotes(r.notes)) spdlog::info("scene: {}", line);
        if (auto line = leftOutSummary(r); !line.empty()) spdlog::info("{}", line);
    }
    int inHistory = 0;  // planes of transient resources kept in idle history memory
    for (const auto& res : g.resources()) inHistory += int(res.historyPlanes.size());
    spdlog::info(
        "{} live passes; memory plan: {} transient planes (aliased from {}{})",
        g.executionOrder().size(), g.transientPlaneCount(), g.unaliasedPlaneCount(),
        inHistory ? fmt::format("; {} planes' worth in idle history memory, at no cost", inHistory)
                  : "");
}

/// --reference: each frame's error against the reference sequence, and their mean.
struct ReferenceCheck {
    std::string pattern, layer;
    std::string measured;  ///< "pass.port" compared; empty: no --reference
    bool failed = false;   ///< a reference frame could not be compared (the run stops)
    std::vector<eval::FrameMetrics> errors;

    /// Throws Error naming the reference file.
    eval::FrameMetrics measure(const Executor& exec, int64_t frame) {
        std::string refPath = expandFramePattern(pattern, frame);
        Image ref = eval::readExrRgb(refPath, layer);
        ImageView out = exec.output(measured);
        if (ref.extent() != out.extent)
            throw FrameError("reference " + refPath + " has another size than the output");
        auto m = eval::compareImages(out, ref.view(), eval::ToneMap::Reinhard,
                                     errors.empty() ? nullptr : &prev_, &cur_);
        std::swap(prev_, cur_);
        errors.push_back(m);
        return m;
    }

private:
    eval::FrameImages prev_, cur_;
};

/// What `kestrel run` prints while the frames run: the progress bar (or a line per frame), the
/// reference error, per-pass times with -v, skipped frames.
class RunLog : public SequenceObserver {
public:
    RunLog(ReferenceCheck& reference, bool openjd) : reference_(reference), openjd_(openjd) {}
    Progress& progress() { return progress_; }

    void starting(const SequencePlan& plan) override {
        for (const auto& [before, after] : plan.gaps)
            spdlog::warn(
                "frames {} and {} of the input are not consecutive (a frame missing, or not a "
                "file): history reset at frame {}, as at a camera cut",
                before, after, after);
        if (plan.everythingWritten)
            spdlog::info("--resume: every frame is already written");
        else if (plan.alreadyWritten > 0)
            spdlog::info("--resume: {} frames already written; warming history up on {} frames",
                         plan.alreadyWritten, plan.replayed);
        progress_ = Progress(plan.schedule.size());
        total_ = plan.schedule.size();
    }

    void frameDone(const FrameRecord& f, size_t index, const Executor& exec) override {
        if (!reference_.measured.empty()) {
            try {
                auto m = reference_.measure(exec, f.frame);
                progress_.clear();
                spdlog::info("frame {}: {:.2f} ms  relMSE {:.5f}  PSNR {:.2f} dB  SSIM {:.4f}",
                             f.frame, f.ms, m.relMse, m.psnr, m.ssim);
            } catch (const Error& e) {
                progress_.clear();
                std::cerr << "error: --reference: " << e.what() << "\n";
                reference_.failed = true;
                return;
            }
        }
        if (gVerbose) {
            std::string detail;
            for (const auto& t : f.passes) detail += fmt::format(" {}={:.2f}", t.pass, t.ms);
            progress_.clear();
            spdlog::debug("frame {}: {:.2f} ms{}", f.frame, f.ms, detail);
        }
        progress_.update(index + 1, f.frame, f.ms, f.written);
        if (openjd_) openjdProgress(index + 1);
    }

    void frameSkipped(const SkippedFrame& s) override {
        progress_.clear();
        spdlog::warn("skipped: {} (history reset)", s.error);
    }

private:
    /// OpenJD's progress message: a worker agent reads `openjd_progress: P` (percent) lines
    /// from the task's standard output and shows them in the scheduler. Warm-up frames count:
    /// they take as long as written ones.
    void openjdProgress(size_t done) const {
        std::printf("openjd_progress: %.1f\n",
                    total_ ? 100.0 * double(done) / double(total_) : 100.0);
        std::fflush(stdout);
    }

    ReferenceCheck& reference_;
    bool openjd_;
    size_t total_ = 0;
    Progress progress_{0};
};

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

/// The closing lines: frames run, median time, memory, mean error; per-pass medians with -v.
void logSummary(const SequenceResult& r, const Executor& exec, const CompiledGraph& compiled,
                const ReferenceCheck& reference) {
    if (r.frames.empty()) return;
    std::vector<double> frameTimes;
    std::map<std::string, std::vector<double>> passTimes;
    for (const auto& f : r.frames) {
        frameTimes.push_back(f.ms);
        for (const auto& t : f.passes) passTimes[t.pass].push_back(t.ms);
    }
    spdlog::info(
        "{} frames run ({} written{}), median {:.2f} ms per frame, {:.1f} MB of graph "
        "memory ({:.0f} bytes per pixel)",
        frameTimes.size(), r.written(),
        r.skipped.empty() ? std::string() : fmt::format(", {} skipped", r.skipped.size()),
        median(frameTimes), exec.memory().peakBytes / 1e6,
        double(exec.memory().peakBytes) / double(std::max<size_t>(1, exec.extent().pixels())));
    // Band scratch the passes could not cut from idle planes (ScratchArena), process-wide.
    spdlog::debug("scratch pool: {:.1f} MB", double(ScratchPool::bytes()) / 1e6);
    if (!reference.errors.empty()) {
        double rel = 0, psnr = 0, ssim = 0;
        for (const auto& m : reference.errors) rel += m.relMse, psnr += m.psnr, ssim += m.ssim;
        double n = double(reference.errors.size());
        spdlog::info("mean error of {} ({} frames): relMSE {:.5f}  PSNR {:.2f} dB  SSIM {:.4f}",
                     reference.measured, reference.errors.size(), rel / n, psnr / n, ssim / n);
    }
    for (const auto& n : compiled.executionOrder())
        if (passTimes.count(n))
            spdlog::debug("  {:<24} {:8.3f} ms median", n, median(passTimes[n]));
}

int runGraph(const RunOptions& o) {
    const auto runStart = std::chrono::steady_clock::now();
    std::unique_ptr<Plugins> plugins;
    std::unique_ptr<CompiledGraph> compiled;
    std::vector<int64_t> frames;
    std::set<int64_t> cuts;
    Extent size{};
    std::string measured;  // "pass.port" compared with --reference
    GraphDesc g;
    try {
        plugins = loadPlugins();
        g = prepareGraph(o.graph, plugins->registry);
        if (!o.frames.empty()) frames = parseFrameList(o.frames);
        if (!o.cuts.empty()) {
            try {
                for (auto f : parseFrameRange(o.cuts)) cuts.insert(f);
            } catch (const Error& e) {
                throw Error(std::string("--cuts: ") + e.what());
            }
        }
        if (!o.size.empty()) {
            if (std::sscanf(o.size.c_str(), "%dx%d", &size.width, &size.height) != 2 ||
                size.width <= 0 || size.height <= 0)
                throw Error("--size " + o.size + ": expected WIDTHxHEIGHT");
        }
        if (!o.reference.empty()) measured = markSinkInput(g, plugins->registry, false);
        CompileOptions copt;
        copt.firstFrame = frames.empty() ? 0 : frames.front();
        copt.fuse = !o.noFuse;
        compiled = compileGraph(g, plugins->registry, copt);
        refuseUnusedOverrides(*compiled, o.graph.sets, plugins->registry);
        if (!o.skipBadFrames)  // a range past the sequence's end fails now, not at its end
            checkFramesExist(frames, sourceFrames(*compiled), "--frames " + o.frames,
                             sourcePath(g, plugins->registry),
                             "give a range inside it, or --skip-bad-frames to skip missing frames");
        if (!o.dumps.empty()) {  // writers for what the compiled graph computes, then again
            const auto dumped = matchDumps(*compiled, o.dumps);
            const fs::path dir =
                o.dumpDir.empty() ? defaultDumpDir(g, plugins->registry) : fs::path(o.dumpDir);
            addDumpWriters(g, dumped, dir);
            compiled = compileGraph(g, plugins->registry, copt);
            spdlog::info("--dump: {} resources to {}", dumped.size(), dir.string());
        }
    } catch (const GraphError& e) {
        printGraphError(e, &g);
        return 2;
    } catch (const Error& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    }
    logReport(*compiled);

    if (frames.empty() && sourceFrames(*compiled).empty()) {
        std::cerr << "error: no frames to run: give --frames A-B\n";
        return 2;
    }
    SequenceOptions so;
    so.frames = frames;
    so.warmup = o.warmup;
    so.resume = o.resume;
    so.skipBadFrames = o.skipBadFrames;
    so.cuts = cuts;
    ReferenceCheck reference;
    reference.pattern = o.reference;
    reference.layer = o.refLayer;
    reference.measured = measured;
    so.stop = [&reference] { return gInterrupted.load() != 0 || reference.failed; };
    SequenceRunner runner(*compiled, so);
    try {
        RunFrames planned;
        for (const auto& f : runner.plan().schedule) {
            planned.read.push_back(f.frame);
            if (f.write) planned.written.push_back(f.frame);
        }
        checkOutputsAreSafe(g, plugins->registry, planned, o.reference, compiled.get());
        // A run killed with kill -9 (or a power loss) left its temporary of the frame it was
        // writing; the frames this run writes are its own to clean.
        if (o.resume)
            removeStaleTemporaries(outputFiles(g, plugins->registry, planned.written),
                                   std::chrono::seconds(0));
    } catch (const Error& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    }

    Parallel parallel(o.threads);
    RunInfo info;
    info.graphName = compiled->desc().name;
    info.graphPath = compiled->desc().sourcePath.string();
    info.kestrelVersion = KESTREL_VERSION;
    Executor exec(*compiled, parallel, info, size);

    gInterrupted = 0;
    auto oldInt = std::signal(SIGINT, onInterrupt);
    auto oldTerm = std::signal(SIGTERM, onInterrupt);
    RunLog log(reference, o.progress == "openjd");
    const SequenceResult result = runner.run(exec, &log);
    std::signal(SIGINT, oldInt);
    std::signal(SIGTERM, oldTerm);
    int rc = 0;
    if (result.end == SequenceEnd::Failed) {
        log.progress().clear();
        std::cerr << "error: " << result.error << "\n";
        rc = 1;
    } else if (reference.failed) {
        rc = 1;  // RunLog printed why
    } else if (result.end == SequenceEnd::Stopped) {
        log.progress().clear();
        const int sig = gInterrupted.load();
        spdlog::warn("interrupted ({}): stopped after frame {}; every written frame is complete",
                     sig == SIGTERM ? "SIGTERM" : "SIGINT", result.lastFrame);
        rc = 128 + (sig == SIGTERM ? SIGTERM : SIGINT);
    }
    log.progress().finish();
    logSummary(result, exec, *compiled, reference);
    // One fixed-format line per run that reached frame 1: `kestrel farm check` reads each task's
    // wall time and outcome from its log (FarmCheck.cpp parses this text; keep them in step).
    spdlog::info(
        "run finished: exit {}, {} frames written, wall {:.2f} s", rc, result.written(),
        std::chrono::duration<double>(std::chrono::steady_clock::now() - runStart).count());
    return rc;
}

}  // namespace

void addRunCommand(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand("run", "Run a graph over a frame sequence");
    auto o = std::make_shared<RunOptions>();
    cmd->add_option("GRAPH", o->graph.graph, "Graph JSON file (default: the shipped svgf.json)");
    cmd->add_option("--input", o->graph.inputs,
                    "Input frames: PATTERN (frame.####.exr, %04d) or name=PATTERN for a named "
                    "loader (default: the built-in scene)")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--output", o->graph.outputs,
                    "Output frames: PATTERN or name=PATTERN (default: kestrel-out/<graph>/)")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--frames", o->frames,
                    "Frames to run: 1-100, 1-100x2, 3,4,10-20x2 (default: all found)");
    cmd->add_option("--set", o->graph.sets, "Override a parameter: pass.param=value (repeatable)")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--threads", o->threads, "Worker threads (default: all cores)")
        ->check(CLI::Range(0, 1024));
    cmd->add_flag("--keep-passes", o->graph.keepPasses,
                  "Also write the input's other channels (AOVs) and header attributes into each "
                  "output EXR (every writer's keepPasses=true)");
    cmd->add_flag("--resume", o->resume,
                  "Skip frames whose output exists, warming history up first");
    cmd->add_option("--warmup", o->warmup, "Run N frames before the range without writing them")
        ->check(CLI::Range(0, 100000));
    cmd->add_option("--cuts", o->cuts,
                    "Camera cuts: frames (7,120 or 7-9) before which history is reset");
    cmd->add_flag("--no-fuse", o->noFuse,
                  "Run every pass on its own (no fused steps; same results, to measure fusion)");
    cmd->add_flag("--skip-bad-frames", o->skipBadFrames,
                  "Skip missing or corrupt frames (history is reset)");
    cmd->add_option(
        "--reference", o->reference,
        "Reference frames: print each frame's error (relMSE, PSNR, SSIM) next to its time");
    cmd->add_option("--ref-layer", o->refLayer, "RGB layer of the reference (default: automatic)");
    cmd->add_option("--size", o->size, "Frame size WxH for graphs without an input pass");
    cmd->add_option("--dump", o->dumps,
                    "Also write every frame of the matching resources as float EXR: pass.port "
                    "or a shell pattern ('*atrous0.color'); repeatable")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--dump-dir", o->dumpDir,
                    "Folder of the --dump files, named pass.port.####.exr (default: dump/ beside "
                    "the first output)");
    cmd->add_option("--out-dir", o->graph.outDir,
                    "Where default outputs and the built-in scene go");
    cmd->add_option("--progress", o->progress,
                    "auto (a bar on a terminal, else a log line per frame) or openjd (also "
                    "`openjd_progress: P` lines on stdout for an OpenJD worker)")
        ->check(CLI::IsMember({"auto", "openjd"}));
    cmd->add_flag("-v,--verbose", gVerbose, "Per-frame and per-pass timings, details of errors");
    cmd->callback([&action, o] { action = [o] { return runGraph(*o); }; });
}

}  // namespace kestrel::cli
