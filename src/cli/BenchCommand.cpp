// kestrel bench: error against a reference versus run time, for several graphs and parameter
// settings over one sequence, as a table on the terminal and a report (Markdown, CSV, HTML).
#include <eval/BenchReport.h>
#include <eval/ExrRgb.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "Commands.h"
#include "Common.h"
#include "DefaultScene.h"
#include "Dump.h"
#include "kestrel/Executor.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Log.h"
#include "kestrel/SequenceRunner.h"

namespace kestrel::cli {

namespace fs = std::filesystem;

namespace {

struct BenchOptions {
    std::vector<std::string> graphs;
    std::vector<std::string> sweeps;
    std::vector<std::string> sets;
    std::string input, reference, frames, refLayer;
    std::string report = "kestrel-out/bench";
    std::string toneMap = "reinhard";
    int threads = 0;
    int warmup = 2;
    int rounds = 3;  ///< each setting's frames run once per round, settings alternating
    bool noInputRow = false;
    bool noFuse = false;
    std::vector<std::string> cropDumps;  ///< intermediates shown as crops in the report
};

/// One graph with one parameter setting.
struct Setting {
    std::string name;
    fs::path graph;
    std::vector<std::string> sets;
    bool inputOnly = false;  ///< the unfiltered input: the error of doing nothing
};

double median(std::vector<double> v) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

/// The values of `--sweep pass.param=v1,v2,...`; an empty list or value is a usage error.
std::vector<std::string> sweepValues(const std::string& sweep, size_t eq) {
    std::vector<std::string> values;
    std::stringstream list(sweep.substr(eq + 1));
    for (std::string v; std::getline(list, v, ',');) {
        if (v.empty())
            throw Error("--sweep " + sweep + ": an empty value (expected pass.param=v1,v2,...)");
        values.push_back(v);
    }
    if (values.empty() || sweep.back() == ',')
        throw Error("--sweep " + sweep + ": no value" +
                    (values.empty() ? "s" : " after the last comma") +
                    " (expected pass.param=v1,v2,...)");
    return values;
}

/// The rows of one sweep on one graph. A graph without the pass (or group parameter) is not
/// swept (empty result, `why` says why); a value the graph refuses is a usage error.
std::vector<Setting> sweepGraph(const GraphDesc& g, const std::string& gpath,
                                const std::string& sweep, const Registry& registry,
                                std::string& why) {
    const size_t eq = sweep.find('=');
    std::vector<Setting> rows;
    std::string refused;
    for (const auto& v : sweepValues(sweep, eq)) {
        const std::string assign = sweep.substr(0, eq) + "=" + v;
        try {  // tried on a copy, as --set would apply it (names, patterns, instance parameters)
            GraphDesc trial = g;
            applyOverride(trial, assign, &registry, "--sweep");
            rows.push_back({g.name + " " + assign, gpath, {assign}, false});
        } catch (const Error& e) {
            if (refused.empty()) refused = e.what();
        }
    }
    // Named as typed when no value took: the name is what is wrong, not one value.
    const std::string prefix = "--sweep " + sweep.substr(0, eq) + "=";
    if (rows.empty() && refused.rfind(prefix, 0) == 0 && refused.find(": ") != std::string::npos)
        why = "--sweep " + sweep + refused.substr(refused.find(": "));
    else if (rows.empty())
        why = refused;
    else if (!refused.empty())
        throw Error(refused);  // the target exists: the value is wrong
    return rows;
}

std::vector<Setting> makeSettings(const BenchOptions& o, const Registry& registry) {
    std::vector<Setting> settings;
    std::vector<std::string> graphs = o.graphs;
    if (graphs.empty())
        for (const char* name : {"svgf.json", "svgf-notaa.json", "svgf-fast.json",
                                 "svgf-split.json", "games202-jbf.json", "games202-atrous.json"}) {
            fs::path p = shippedGraph(name);
            std::error_code ec;
            if (fs::exists(p, ec)) graphs.push_back(p.string());
        }
    if (graphs.empty()) throw Error("no graphs to bench");
    if (!o.noInputRow) settings.push_back({"input (unfiltered)", graphs.front(), {}, true});
    std::map<std::string, std::string> unmatched;  // sweep -> why the first graph refused it
    for (const auto& sweep : o.sweeps) {
        auto eq = sweep.find('=');
        auto dot = eq == std::string::npos ? std::string::npos : sweep.rfind('.', eq);
        if (eq == std::string::npos || dot == std::string::npos)
            throw Error("--sweep " + sweep + ": expected pass.param=v1,v2,...");
        unmatched[sweep] = "";
    }
    for (const auto& gpath : graphs) {
        GraphDesc g = loadGraphFile(gpath);
        bool swept = false;
        for (const auto& sweep : o.sweeps) {
            std::string why;
            auto rows = sweepGraph(g, gpath, sweep, registry, why);
            if (rows.empty() && unmatched[sweep].empty()) unmatched[sweep] = why;
            if (!rows.empty()) unmatched.erase(sweep);
            swept = swept || !rows.empty();
            settings.insert(settings.end(), rows.begin(), rows.end());
        }
        if (!swept) settings.push_back({g.name, gpath, {}, false});
    }
    // A sweep no graph takes would bench the same graph once per value: refused, with the
    // first graph's reason (a did-you-mean).
    for (const auto& sweep : o.sweeps)
        if (auto it = unmatched.find(sweep); it != unmatched.end())
            throw Error(it->second.empty() ? "--sweep " + sweep + ": no benched graph has it"
                                           : it->second);
    return settings;
}

Image cropOf(const ImageView& img, int x0, int y0, int w, int h) {
    Image c(w, h, Format::Float3);
    for (int ch = 0; ch < 3; ++ch)
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                c.at(ch, x, y) = img.at(std::min(ch, img.channels() - 1), x0 + x, y0 + y);
    return c;
}

/// A whole frame as linear RGB (Float3): the report cuts its crops from it where the error is
/// worst, which is known only once every setting has run.
Image wholeFrame(const ImageView& img) {
    return cropOf(img, 0, 0, img.width(), img.height());
}

/// What every setting shares: the input, reference, frames and the report being filled.
struct BenchRun {
    const BenchOptions& options;
    const Registry& registry;
    std::string input, reference;
    eval::ToneMap toneMap;
    std::vector<int64_t> frames;
    size_t cropFrame;  ///< index into frames of the frame the crops show
    eval::BenchReport report;
};

/// A setting compiled for this input, or why it cannot run on it.
struct Prepared {
    std::unique_ptr<CompiledGraph> compiled;
    std::string marked;              ///< "pass.port" compared with the reference
    std::set<std::string> sources;   ///< passes whose time is load time
    std::vector<std::string> crops;  ///< intermediates shown as crops (--crop-dump)
    std::string error;               ///< not empty: the setting is skipped
};

/// Loads the setting's graph on the input, marks the compared output (writers detached) and the
/// --crop-dump matches, and compiles it. A GraphError is the user's to fix and propagates; an
/// Error (a graph this scene cannot feed) makes the setting skipped.
Prepared prepare(const Setting& s, const BenchRun& b) {
    Prepared p;
    try {
        GraphDesc g = loadGraphFile(s.graph);
        std::string source;
        for (const auto& n : g.passes)
            if (const PassType* t = b.registry.find(n.type); t && isSource(*t)) {
                source = n.name;
                break;
            }
        if (source.empty()) throw Error("graph " + s.graph.string() + " has no input pass");
        applyOverride(g, source + ".path=" + nlohmann::json(b.input).dump(), &b.registry,
                      "--input");
        for (const auto& set : b.options.sets) applyOverride(g, set, &b.registry);
        for (const auto& set : s.sets) applyOverride(g, set, &b.registry, "--sweep");
        if (s.inputOnly) {
            g.passes.erase(std::remove_if(g.passes.begin(), g.passes.end(),
                                          [&](const PassNode& n) { return n.name != source; }),
                           g.passes.end());
            g.edges.clear();
            g.outputs = {source + ".color"};
            p.marked = g.outputs.front();
        } else {
            p.marked = markSinkInput(g, b.registry, true);
        }
        CompileOptions copt;
        copt.firstFrame = b.frames.front();
        copt.fuse = !b.options.noFuse;
        p.compiled = compileGraph(g, b.registry, copt);
        if (!s.inputOnly) {  // tuning that changes nothing here gives identical rows
            refuseUnusedOverrides(*p.compiled, b.options.sets, b.registry, "--set");
            refuseUnusedOverrides(*p.compiled, s.sets, b.registry, "--sweep");
        }
        for (const auto& pattern : b.options.cropDumps)
            for (const auto& r : matchResources(*p.compiled, pattern))
                if (std::find(p.crops.begin(), p.crops.end(), r) == p.crops.end())
                    p.crops.push_back(r);
        if (!p.crops.empty()) {  // marked outputs stay readable after the frame
            for (const auto& r : p.crops)
                if (std::find(g.outputs.begin(), g.outputs.end(), r) == g.outputs.end())
                    g.outputs.push_back(r);
            p.compiled = compileGraph(g, b.registry, copt);
        }
        for (const auto& n : g.passes)
            if (const PassType* t = b.registry.find(n.type); t && isSourceType(*t))
                p.sources.insert(n.name);
    } catch (const GraphError&) {
        throw;
    } catch (const Error& e) {
        p.compiled.reset();
        p.error = e.what();
    }
    return p;
}

/// Per frame of one setting: load and compute time (after the warm-up), the error against the
/// reference, and the crops of the output and of the chosen intermediates.
class BenchFrames : public SequenceObserver {
public:
    /// `measure`: compare with the reference and take the crops (the first round); the other
    /// rounds only time.
    BenchFrames(BenchRun& b, const Setting& s, const Prepared& p, eval::BenchRow& row, bool measure)
        : b_(b), s_(s), p_(p), row_(row), measure_(measure) {}

    void frameDone(const FrameRecord& f, size_t i, const Executor& exec) override {
        const bool timed =
            i >= size_t(b_.options.warmup) || b_.frames.size() <= size_t(b_.options.warmup);
        double compute = 0, load = 0;
        std::map<std::string, double> passes;
        for (const auto& t : f.passes) {
            (p_.sources.count(t.pass) ? load : compute) += t.ms;
            if (!p_.sources.count(t.pass)) passes[t.pass] += t.ms;
        }
        if (timed) {
            computeMs.push_back(compute);
            loadMs.push_back(load);
            passMs.push_back(std::move(passes));
        }
        if (!measure_) return;
        ImageView out = exec.output(p_.marked);
        const bool cropFrame = i == b_.cropFrame;
        if (!b_.reference.empty()) compare(out, f.frame, cropFrame);
        if (cropFrame) {
            row_.frame = wholeFrame(out);
            for (const auto& r : p_.crops)
                row_.intermediateFrames.push_back({r, wholeFrame(exec.output(r))});
            b_.report.cropFrameNumber = f.frame;
            if (s_.inputOnly) b_.report.noisyFrame = wholeFrame(out);
        }
    }

    std::vector<double> computeMs, loadMs;
    std::vector<std::map<std::string, double>> passMs;  ///< per timed frame, compute passes

private:
    /// Throws FrameError when the reference frame has another size than the output.
    void compare(const ImageView& out, int64_t frame, bool cropFrame) {
        const std::string path = expandFramePattern(b_.reference, frame);
        Image ref = eval::readExrRgb(path, b_.options.refLayer);
        if (ref.extent() != out.extent)
            throw FrameError("reference " + path + " is " + std::to_string(ref.width()) + "x" +
                             std::to_string(ref.height()) + ", output is " +
                             std::to_string(out.width()) + "x" + std::to_string(out.height()));
        row_.errors.push_back(
            eval::compareImages(out, ref.view(), b_.toneMap, havePrev_ ? &prev_ : nullptr, &cur_));
        std::swap(prev_, cur_);
        havePrev_ = true;
        if (cropFrame && b_.report.referenceFrame.width() == 0)
            b_.report.referenceFrame = wholeFrame(ref.view());
    }

    BenchRun& b_;
    const Setting& s_;
    const Prepared& p_;
    eval::BenchRow& row_;
    bool measure_;
    eval::FrameImages prev_, cur_;
    bool havePrev_ = false;
};

/// One setting's timings pooled over the rounds.
struct Timings {
    std::vector<double> computeMs, loadMs, roundMedians;
    std::vector<std::map<std::string, double>> passMs;  ///< per timed frame

    /// The timed frame whose compute time is the median: its per-pass times add up to the
    /// setting's ms per frame (medians taken pass by pass would not).
    size_t medianFrame() const {
        std::vector<size_t> idx(computeMs.size());
        for (size_t k = 0; k < idx.size(); ++k) idx[k] = k;
        std::sort(idx.begin(), idx.end(),
                  [&](size_t a, size_t c) { return computeMs[a] < computeMs[c]; });
        return idx.empty() ? 0 : idx[idx.size() / 2];
    }
};

/// Runs one prepared setting over the frames once (a round): the first round also measures the
/// error and takes the crops into `row`; every round adds its timings to `t`.
void runRound(BenchRun& b, const Setting& s, Prepared& p, eval::BenchRow& row, Timings& t,
              bool first) {
    Parallel parallel(b.options.threads);
    RunInfo info;
    info.graphName = p.compiled->desc().name;
    Executor exec(*p.compiled, parallel, info);
    BenchFrames frames(b, s, p, row, first);
    SequenceOptions so;
    so.frames = b.frames;
    so.writeOutputs = false;  // the writers are detached; nothing is written
    const SequenceResult result = SequenceRunner(*p.compiled, so).run(exec, &frames);
    if (result.end == SequenceEnd::Failed) throw Error(result.error);
    t.roundMedians.push_back(median(frames.computeMs));
    t.computeMs.insert(t.computeMs.end(), frames.computeMs.begin(), frames.computeMs.end());
    t.loadMs.insert(t.loadMs.end(), frames.loadMs.begin(), frames.loadMs.end());
    t.passMs.insert(t.passMs.end(), frames.passMs.begin(), frames.passMs.end());
}

/// Fills the row's timings from all rounds and prints its line of the table.
void finishSetting(BenchRun& b, const Setting& s, const Prepared& p, eval::BenchRow& row,
                   const Timings& t) {
    row.name = s.name;
    row.inputOnly = s.inputOnly;
    if (!s.inputOnly && !t.computeMs.empty()) {
        row.msPerFrame = median(t.computeMs);
        const auto [lo, hi] = std::minmax_element(t.roundMedians.begin(), t.roundMedians.end());
        row.msMin = *lo, row.msMax = *hi;
        const auto& passes = t.passMs[t.medianFrame()];
        for (const auto& n : p.compiled->executionOrder())
            if (auto it = passes.find(n); it != passes.end()) row.passMs.push_back(*it);
    }
    auto m = row.mean();
    if (!b.reference.empty())
        std::printf("%-34s %10.5f %7.2f %6.3f %9.5f %8.0f %10.2f %9.2f\n", s.name.c_str(), m.relMse,
                    m.psnr, m.ssim, m.temporal.value_or(0.0), m.speckles, row.msPerFrame,
                    median(t.loadMs));
    else
        std::printf("%-34s %10s %7s %6s %9s %8s %10.2f %9.2f\n", s.name.c_str(), "-", "-", "-", "-",
                    "-", row.msPerFrame, median(t.loadMs));
    std::fflush(stdout);
}

/// Throws Error (a usage error) naming a --crop-dump pattern no setting computes.
void checkCropPatterns(const BenchOptions& o, const std::vector<Prepared>& prepared) {
    for (const auto& pattern : o.cropDumps) {
        const bool any = std::any_of(prepared.begin(), prepared.end(), [&](const Prepared& p) {
            return p.compiled && !matchResources(*p.compiled, pattern).empty();
        });
        if (!any)
            throw Error("--crop-dump '" + pattern +
                        "' matches no resource any benched graph computes for this input "
                        "(kestrel run --dump lists what a graph computes)");
    }
}

/// The input, frames and tone map of the bench; throws Error (a usage error) naming the option.
void setUpRun(BenchRun& b) {
    const BenchOptions& o = b.options;
    if (b.input.empty()) {
        fs::path scene = ensureDefaultScene(fs::path("kestrel-out") / "default-scene");
        b.input = (scene / "noisy" / "frame_####.exr").string();
        if (b.reference.empty()) b.reference = (scene / "ref" / "frame_####.exr").string();
        spdlog::info("bench: no --input given; using the built-in scene in {}", scene.string());
    }
    auto tm = eval::parseToneMap(o.toneMap);
    if (!tm) throw Error("--tonemap " + o.toneMap + ": expected reinhard, clamp or srgb");
    b.toneMap = *tm;
    b.frames = o.frames.empty() ? findFrames(b.input) : parseFrameList(o.frames);
    if (b.frames.empty()) throw Error("--input " + b.input + ": no frames found");
    if (!o.frames.empty())  // a range past the sequence's end fails before any setting runs
        checkFramesExist(b.frames, findFrames(b.input), "--frames " + o.frames, b.input);
    b.report.title = "kestrel bench";
    b.report.frames = b.frames;
    b.report.toneMap = *tm;
    b.cropFrame = b.frames.size() / 2;
}

/// Throws GraphError, one line per distinct reason, when no graph compiles for this input:
/// the same mistake `run` refuses with exit 2 (the input row alone benches nothing).
void refuseWhenNoGraphPrepares(const std::vector<Setting>& settings,
                               const std::vector<Prepared>& prepared) {
    std::vector<Diagnostic> reasons;
    for (size_t i = 0; i < settings.size(); ++i) {
        if (settings[i].inputOnly) continue;
        if (prepared[i].error.empty()) return;
        const bool seen = std::any_of(reasons.begin(), reasons.end(), [&](const Diagnostic& d) {
            return d.message == prepared[i].error;
        });
        if (!seen) reasons.push_back({settings[i].graph.string(), prepared[i].error});
    }
    if (!reasons.empty()) throw GraphError(std::move(reasons));
}

int runBench(const BenchOptions& o) {
    auto plugins = loadPlugins();
    BenchRun b{o, plugins->registry, o.input, o.reference, eval::ToneMap::Reinhard, {}, 0, {}};
    std::vector<Setting> settings;
    std::vector<Prepared> prepared;
    // Every mistake found before the first frame is a usage error, exit 2, as for `run`.
    const int usage = exitTwoOnUsageError([&] {
        setUpRun(b);
        settings = makeSettings(o, plugins->registry);
        for (const auto& s : settings) prepared.push_back(prepare(s, b));
        refuseWhenNoGraphPrepares(settings, prepared);
        checkCropPatterns(o, prepared);
        return 0;
    });
    if (usage != 0) return usage;
    std::printf("%-34s %10s %7s %6s %9s %8s %10s %9s\n", "graph / setting", "relMSE", "PSNR",
                "SSIM", "temporal", "speckles", "ms/frame", "load ms");
    // Rounds alternate the settings so that a slow spell of the machine (another job, the
    // clock) falls on all of them, and the spread over rounds shows how far timings are noise.
    std::vector<eval::BenchRow> rows(settings.size());
    std::vector<Timings> timings(settings.size());
    std::vector<std::string> failed(settings.size());
    for (size_t i = 0; i < settings.size(); ++i) failed[i] = prepared[i].error;
    for (int round = 0; round < o.rounds; ++round)
        for (size_t i = 0; i < settings.size(); ++i) {
            if (!failed[i].empty()) continue;
            try {
                runRound(b, settings[i], prepared[i], rows[i], timings[i], round == 0);
            } catch (const Error& e) {
                failed[i] = e.what();
            }
        }
    int skipped = 0;
    std::string firstFailure;
    for (size_t i = 0; i < settings.size(); ++i) {
        if (failed[i].empty()) {
            finishSetting(b, settings[i], prepared[i], rows[i], timings[i]);
            b.report.rows.push_back(std::move(rows[i]));
        } else {
            // A graph this scene cannot feed (e.g. a split graph on a scene without the split) is
            // reported and skipped; the other rows still make a report.
            std::printf("%-34s skipped: %s\n", settings[i].name.c_str(), failed[i].c_str());
            if (firstFailure.empty()) firstFailure = failed[i];
            ++skipped;
        }
        prepared[i].compiled.reset();  // its passes are done with
    }
    if (b.report.rows.empty())  // every setting failed during its frames: a runtime failure
        throw Error("no graph could run on this input: " + firstFailure);
    if (skipped) spdlog::warn("{} setting(s) skipped: the input cannot feed them", skipped);
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("peak resident memory of the bench process: %.1f MB; %d thread(s)\n",
                double(ru.ru_maxrss) / 1024.0, Parallel(o.threads).threadCount());
    if (b.reference.empty()) {
        spdlog::info("no --reference: timings only, no report written");
        return 0;
    }
    auto files = eval::writeBenchReport(b.report, o.report);
    spdlog::info("report: {} (and {}, {})", files.html.string(), files.markdown.string(),
                 files.csv.string());
    return 0;
}

}  // namespace

void addBenchCommand(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand(
        "bench", "Error against a reference versus run time, per graph and setting");
    auto o = std::make_shared<BenchOptions>();
    cmd->add_option("GRAPH", o->graphs, "Graphs to compare (default: the shipped graphs)");
    cmd->add_option("--sweep", o->sweeps,
                    "Sweep a parameter: pass.param=v1,v2,... (one row per value)")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--set", o->sets, "Override a parameter in every graph: pass.param=value")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--input", o->input, "Noisy frames (default: the built-in scene)");
    cmd->add_option("--reference", o->reference,
                    "Reference frames (default with the built-in scene: its reference)");
    cmd->add_option("--ref-layer", o->refLayer, "RGB layer of the reference (default: automatic)");
    cmd->add_option("--frames", o->frames, "Frames: 1-100, 1-100x2 (default: all found)");
    cmd->add_option("--threads", o->threads, "Worker threads (default: all cores)")
        ->check(CLI::Range(0, 1024));
    cmd->add_option("--warmup", o->warmup, "Frames left out of the timing medians")
        ->check(CLI::Range(0, 1000));
    cmd->add_option("--rounds", o->rounds,
                    "Timing rounds: every setting's frames run once per round, the settings "
                    "alternating; the report shows the spread over the rounds (default 3)")
        ->check(CLI::Range(1, 100));
    cmd->add_option("--report", o->report, "Report folder");
    cmd->add_option("--tonemap", o->toneMap, "Tone map of PSNR/SSIM: reinhard, clamp, srgb");
    cmd->add_flag("--no-input-row", o->noInputRow, "Leave out the unfiltered-input row");
    cmd->add_flag("--no-fuse", o->noFuse,
                  "Run every pass on its own (no fused steps; same results, to measure fusion)");
    cmd->add_option("--crop-dump", o->cropDumps,
                    "Show the matching intermediate resources (pass.port or a shell pattern such "
                    "as '*atrous0.color') as crops beside each setting's output in the report; "
                    "repeatable")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->callback([&action, o] {
        action = [o]() -> int {
            try {
                return runBench(*o);
            } catch (const GraphError& e) {
                printGraphError(e);
                return 2;
            }
        };
    });
}

}  // namespace kestrel::cli
