// kestrel bench: error against a reference versus run time, for several graphs and parameter
// settings over one sequence, as a table on the terminal and a report (Markdown, CSV, HTML).
#include <eval/BenchReport.h>
#include <eval/ExrRgb.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "Commands.h"
#include "Common.h"
#include "DefaultScene.h"
#include "kestrel/Executor.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Log.h"

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
    bool noInputRow = false;
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

std::vector<Setting> makeSettings(const BenchOptions& o) {
    std::vector<Setting> settings;
    std::vector<std::string> graphs = o.graphs;
    if (graphs.empty())
        for (const char* name : {"svgf.json", "svgf-notaa.json", "svgf-split.json",
                                 "games202-jbf.json", "games202-atrous.json"}) {
            fs::path p = shippedGraph(name);
            std::error_code ec;
            if (fs::exists(p, ec)) graphs.push_back(p.string());
        }
    if (graphs.empty()) throw Error("no graphs to bench");
    if (!o.noInputRow) settings.push_back({"input (unfiltered)", graphs.front(), {}, true});
    for (const auto& gpath : graphs) {
        GraphDesc g = loadGraphFile(gpath);
        std::string base = g.name;
        bool swept = false;
        for (const auto& sweep : o.sweeps) {
            auto eq = sweep.find('=');
            auto dot = eq == std::string::npos ? std::string::npos : sweep.rfind('.', eq);
            if (eq == std::string::npos || dot == std::string::npos)
                throw Error("--sweep " + sweep + ": expected pass.param=v1,v2,...");
            // A graph without the pass (or group parameter) is not swept: the assignment is
            // tried on a copy, as --set would apply it (names, patterns, instance parameters).
            try {
                GraphDesc trial = g;
                applyOverride(trial, sweep.substr(0, eq) + "=0");
            } catch (const Error&) {
                continue;
            }
            std::stringstream values(sweep.substr(eq + 1));
            for (std::string v; std::getline(values, v, ',');) {
                if (v.empty()) continue;
                std::string assign = sweep.substr(0, eq) + "=" + v;
                settings.push_back({base + " " + assign, gpath, {assign}, false});
                swept = true;
            }
        }
        if (!swept) settings.push_back({base, gpath, {}, false});
    }
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

int runBench(const BenchOptions& o) {
    auto plugins = loadPlugins();
    const Registry& reg = plugins->registry;
    std::string input = o.input, reference = o.reference;
    if (input.empty()) {
        fs::path scene = ensureDefaultScene(fs::path("kestrel-out") / "default-scene");
        input = (scene / "noisy" / "frame_####.exr").string();
        if (reference.empty()) reference = (scene / "ref" / "frame_####.exr").string();
        spdlog::info("bench: no --input given; using the built-in scene in {}", scene.string());
    }
    auto tm = eval::parseToneMap(o.toneMap);
    if (!tm) throw Error("--tonemap " + o.toneMap + ": expected reinhard, clamp or srgb");
    std::vector<int64_t> frames;
    if (!o.frames.empty())
        frames = parseFrameList(o.frames);
    else
        frames = findFrames(input);
    if (frames.empty()) throw Error("--input " + input + ": no frames found");

    eval::BenchReport report;
    report.title = "kestrel bench";
    report.frames = frames;
    report.toneMap = *tm;
    const size_t cropFrame = frames.size() / 2;

    std::vector<Setting> settings = makeSettings(o);
    std::printf("%-34s %10s %7s %6s %9s %10s %9s\n", "graph / setting", "relMSE", "PSNR", "SSIM",
                "temporal", "ms/frame", "load ms");
    int skipped = 0;
    for (const auto& s : settings) {
        try {
            GraphDesc g = loadGraphFile(s.graph);
            std::string source;
            for (const auto& p : g.passes)
                if (const PassType* t = reg.find(p.type); t && isSource(*t)) {
                    source = p.name;
                    break;
                }
            if (source.empty()) throw Error("graph " + s.graph.string() + " has no input pass");
            applyOverride(g, source + ".path=" + nlohmann::json(input).dump());
            for (const auto& set : o.sets) applyOverride(g, set);
            for (const auto& set : s.sets) applyOverride(g, set);
            std::string marked;
            if (s.inputOnly) {
                g.passes.erase(std::remove_if(g.passes.begin(), g.passes.end(),
                                              [&](const PassNode& p) { return p.name != source; }),
                               g.passes.end());
                g.edges.clear();
                g.outputs = {source + ".color"};
                marked = g.outputs.front();
            } else {
                marked = markSinkInput(g, reg, true);
            }
            CompileOptions copt;
            copt.firstFrame = frames.front();
            auto compiled = compileGraph(g, reg, copt);
            std::set<std::string> sources;
            for (const auto& p : g.passes)
                if (const PassType* t = reg.find(p.type); t && isSourceType(*t))
                    sources.insert(p.name);

            Parallel parallel(o.threads);
            RunInfo info;
            info.graphName = g.name;
            Executor exec(*compiled, parallel, info);
            exec.beginRun(frames.front(), frames.back());
            eval::BenchRow row;
            row.name = s.name;
            std::vector<double> computeMs, loadMs;
            std::map<std::string, std::vector<double>> passMs;
            eval::FrameImages prev, cur;
            bool havePrev = false;
            for (size_t i = 0; i < frames.size(); ++i) {
                exec.runFrame(frames[i], false);
                double compute = 0, load = 0;
                for (const auto& t : exec.lastTimes()) {
                    if (sources.count(t.pass))
                        load += t.ms;
                    else
                        compute += t.ms;
                    if (i >= size_t(o.warmup) || frames.size() <= size_t(o.warmup))
                        passMs[t.pass].push_back(t.ms);
                }
                if (i >= size_t(o.warmup) || frames.size() <= size_t(o.warmup)) {
                    computeMs.push_back(compute);
                    loadMs.push_back(load);
                }
                ImageView out = exec.output(marked);
                if (!reference.empty()) {
                    Image ref =
                        eval::readExrRgb(expandFramePattern(reference, frames[i]), o.refLayer);
                    if (ref.extent() != out.extent)
                        throw FrameError("reference " + expandFramePattern(reference, frames[i]) +
                                         " is " + std::to_string(ref.width()) + "x" +
                                         std::to_string(ref.height()) + ", output is " +
                                         std::to_string(out.width()) + "x" +
                                         std::to_string(out.height()));
                    row.errors.push_back(eval::compareImages(out, ref.view(), *tm,
                                                             havePrev ? &prev : nullptr, &cur));
                    std::swap(prev, cur);
                    havePrev = true;
                    if (i == cropFrame && report.referenceCrop.width() == 0) {
                        int w = std::min(128, out.width()), h = std::min(128, out.height());
                        report.referenceCrop =
                            cropOf(ref.view(), (out.width() - w) / 2, (out.height() - h) / 2, w, h);
                    }
                }
                if (i == cropFrame) {
                    int w = std::min(128, out.width()), h = std::min(128, out.height());
                    int x0 = (out.width() - w) / 2, y0 = (out.height() - h) / 2;
                    row.crop = cropOf(out, x0, y0, w, h);
                    report.cropNote = "frame " + std::to_string(frames[i]) + ", x " +
                                      std::to_string(x0) + "-" + std::to_string(x0 + w - 1) +
                                      ", y " + std::to_string(y0) + "-" +
                                      std::to_string(y0 + h - 1);
                    if (s.inputOnly) report.noisyCrop = cropOf(out, x0, y0, w, h);
                }
            }
            exec.endRun();
            row.msPerFrame = s.inputOnly ? 0.0 : median(computeMs);
            for (const auto& n : compiled->executionOrder())
                if (!sources.count(n) && passMs.count(n))
                    row.passMs.push_back({n, median(passMs[n])});
            auto m = row.mean();
            if (!reference.empty())
                std::printf("%-34s %10.5f %7.2f %6.3f %9.5f %10.2f %9.2f\n", s.name.c_str(),
                            m.relMse, m.psnr, m.ssim, m.temporal.value_or(0.0), row.msPerFrame,
                            median(loadMs));
            else
                std::printf("%-34s %10s %7s %6s %9s %10.2f %9.2f\n", s.name.c_str(), "-", "-", "-",
                            "-", row.msPerFrame, median(loadMs));
            std::fflush(stdout);
            report.rows.push_back(std::move(row));
        } catch (const GraphError&) {
            throw;
        } catch (const Error& e) {
            // A graph this scene cannot feed (e.g. a split graph on a scene without the split) is
            // reported and skipped; the other rows still make a report.
            std::printf("%-34s skipped: %s\n", s.name.c_str(), e.what());
            ++skipped;
        }
    }
    if (report.rows.empty()) throw Error("no graph could run on this input");
    if (skipped) spdlog::warn("{} setting(s) skipped: the input cannot feed them", skipped);
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("peak resident memory of the bench process: %.1f MB; %d thread(s)\n",
                double(ru.ru_maxrss) / 1024.0, Parallel(o.threads).threadCount());
    if (reference.empty()) {
        spdlog::info("no --reference: timings only, no report written");
        return 0;
    }
    auto files = eval::writeBenchReport(report, o.report);
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
    cmd->add_option("--report", o->report, "Report folder");
    cmd->add_option("--tonemap", o->toneMap, "Tone map of PSNR/SSIM: reinhard, clamp, srgb");
    cmd->add_flag("--no-input-row", o->noInputRow, "Leave out the unfiltered-input row");
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
