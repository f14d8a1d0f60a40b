#include "FarmCheck.h"

#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <set>

#include "Common.h"
#include "OutputSafety.h"
#include "kestrel/Compiler.h"
#include "kestrel/Error.h"
#include "kestrel/FramePattern.h"
#include "kestrel/InputFiles.h"
#include "kestrel/Log.h"

namespace kestrel::cli {

namespace fs = std::filesystem;

namespace {

enum class FrameState { Complete, Missing, Broken, Foreign };

struct Writer {
    std::string name;
    FramePattern path;
    const Pass* pass;
};

std::vector<Writer> planWriters(const FarmPlan& plan, const CompiledGraph& g) {
    std::vector<Writer> writers;
    for (const auto& [name, pass] : g.sinks()) {
        for (const auto& n : g.desc().passes) {
            if (n.name != name) continue;
            auto params = nlohmann::json::parse(n.paramsJson);
            if (params.contains("path") && params["path"].is_string())
                writers.push_back({name, FramePattern(params["path"].get<std::string>()), pass});
        }
    }
    if (writers.empty()) throw Error(plan.graph + ": the graph writes no files to check");
    return writers;
}

/// A parameter value as the provenance JSON spells it, short.
std::string shortValue(const nlohmann::json& v) {
    std::string s = v.dump();
    return s.size() > 40 ? s.substr(0, 37) + "..." : s;
}

/// What differs between the provenance an output records and the plan's: the graph, else the
/// passes and parameters (the first three), so that the user knows which run made it.
std::string provenanceDifference(const std::string& recorded, const std::string& planned) {
    if (recorded.empty()) return "it records no kestrel.provenance (another writer's file?)";
    const auto r = nlohmann::json::parse(recorded, nullptr, false);
    const auto p = nlohmann::json::parse(planned, nullptr, false);
    if (!r.is_object() || !r.contains("passes") || !r["passes"].is_array())
        return "its kestrel.provenance is not Kestrel's JSON";
    if (r.value("graph", "") != p.value("graph", ""))
        return "graph '" + r.value("graph", "") + "' (the plan's: '" + p.value("graph", "") + "')";
    std::map<std::string, nlohmann::json> rp, pp;  // pass name -> params
    for (const auto& n : r["passes"]) rp[n.value("name", "")] = n.value("params", nlohmann::json());
    for (const auto& n : p["passes"]) pp[n.value("name", "")] = n.value("params", nlohmann::json());
    std::vector<std::string> diffs, paths;  // file patterns last: the parameters say more
    for (const auto& [name, params] : pp) {
        if (!rp.count(name)) {
            diffs.push_back("no pass " + name);
            continue;
        }
        for (const auto& [k, v] : params.items())
            if (!rp[name].contains(k) || rp[name][k] != v)
                (k == "path" ? paths : diffs)
                    .push_back(name + "." + k + " " +
                               (rp[name].contains(k) ? shortValue(rp[name][k]) : "unset") +
                               " (the plan's: " + shortValue(v) + ")");
    }
    diffs.insert(diffs.end(), paths.begin(), paths.end());
    for (const auto& [name, params] : rp)
        if (!pp.count(name)) diffs.push_back("pass " + name + " the plan's graph has not");
    if (diffs.empty()) return "its passes are in another order";
    std::string s;
    for (size_t i = 0; i < std::min<size_t>(3, diffs.size()); ++i) s += (i ? ", " : "") + diffs[i];
    if (diffs.size() > 3) s += fmt::format(" and {} more", diffs.size() - 3);
    return s;
}

/// The state of one frame over every writer; `file` names the first file that is not
/// complete, `why` says what made a foreign one.
FrameState frameState(const std::vector<Writer>& writers, int64_t frame,
                      const std::string& provenance, std::string& file, std::string& why) {
    for (const auto& w : writers) {
        file = w.path.expand(frame);
        std::error_code ec;
        if (!fs::exists(file, ec)) return FrameState::Missing;
        // The writer's own rule; it warns that it would rewrite the file, which is not news here.
        const auto level = spdlog::get_level();
        spdlog::set_level(spdlog::level::err);
        const bool complete = w.pass->frameWritten(frame, "");
        spdlog::set_level(level);
        if (!complete) return FrameState::Broken;
        // --resume would run it again too: a frame of another graph or other parameters is not
        // this plan's output, however intact.
        const std::string recorded = w.pass->recordedProvenance(frame);
        if (recorded != provenance) {
            why = provenanceDifference(recorded, provenance);
            return FrameState::Foreign;
        }
    }
    return FrameState::Complete;
}

/// "missing", "broken " or "foreign": the frame lines' first word (aligned).
const char* stateWord(FrameState s) {
    switch (s) {
        case FrameState::Missing:
            return "missing";
        case FrameState::Broken:
            return "broken ";
        default:
            return "foreign";
    }
}

std::string taskLine(const FarmTask& t, bool rerun, const TaskLog& log) {
    std::string frames = std::to_string(t.first) + "-" + std::to_string(t.last);
    std::string s = fmt::format("task {:<4} frames {:<13} {:<9}", t.index, frames,
                                rerun ? "RE-RUN" : "complete");
    if (!log.found) return s + " no log (" + t.log + ")";
    if (log.attempts == 0)
        return s + " no run finished in the log" +
               (log.lastError.empty() ? "" : ": " + log.lastError);
    s += fmt::format(" wall {:.2f} s, {} frames written, exit {}", log.wallSeconds, log.written,
                     log.exitCode);
    if (log.attempts > 1) s += fmt::format(" (attempt {})", log.attempts);
    return s;
}

}  // namespace

TaskLog readTaskLog(const std::string& path) {
    TaskLog r;
    // The same rule as every input (InputFiles.h); a log is optional, so what is not a regular
    // file reads as no log, not an error.
    try {
        checkRegularFile(path, "task log");
    } catch (const Error&) {
        return r;
    }
    std::ifstream in(path);
    if (!in) return r;
    r.found = true;
    // Written by RunCommand.cpp at the end of every run that reached frame 1.
    static const std::regex finished(
        R"(run finished: exit (\d+), (\d+) frames written, wall ([0-9.]+) s)");
    std::string line;
    while (std::getline(in, line)) {
        std::smatch m;
        if (std::regex_search(line, m, finished)) {
            ++r.attempts;
            r.exitCode = std::stoi(m[1]);
            r.written = std::stoi(m[2]);
            r.wallSeconds = std::stod(m[3]);
        } else if (line.rfind("error:", 0) == 0) {
            r.lastError = line;
        }
    }
    return r;
}

int checkPlan(const FarmPlan& plan) {
    auto plugins = loadPlugins();
    GraphOptions go;
    go.graph = plan.graph;
    go.inputs = plan.inputs;
    go.outputs = plan.outputs;
    go.sets = plan.sets;
    GraphDesc desc = prepareGraph(go, plugins->registry);
    CompileOptions copt;
    copt.firstFrame = plan.first;
    auto compiled = compileGraph(desc, plugins->registry, copt);
    const auto writers = planWriters(plan, *compiled);
    // Temporaries of killed tasks. A task may be running on another node, where its pid means
    // nothing here: only those untouched for a minute (a frame is written in seconds) go.
    std::vector<std::string> files;
    for (const auto& w : writers)
        for (int64_t f = plan.first; f <= plan.last; ++f) files.push_back(w.path.expand(f));
    removeStaleTemporaries(files, std::chrono::seconds(60));

    const std::string provenance = compiled->provenanceJson();
    std::set<int> rerun;
    std::map<FrameState, int> count;
    for (int64_t f = plan.first; f <= plan.last; ++f) {
        std::string file, why;
        const FrameState s = frameState(writers, f, provenance, file, why);
        if (s == FrameState::Complete) continue;
        const FarmTask* t = plan.taskOf(f);
        if (t) rerun.insert(t->index);
        ++count[s];
        std::cout << stateWord(s) << " frame " << f << ": " << file
                  << (s == FrameState::Broken ? " (incomplete or unreadable EXR)" : "")
                  << (s == FrameState::Foreign
                          ? " (written by another graph or other parameters: " + why + ")"
                          : "")
                  << (t ? " (task " + std::to_string(t->index) + ")" : "") << "\n";
    }
    const int64_t total = plan.last - plan.first + 1;
    const int missing = count[FrameState::Missing], broken = count[FrameState::Broken],
              foreign = count[FrameState::Foreign];
    std::cout << fmt::format(
        "farm check: frames {}-{} in {} tasks: {} complete, {} missing, {} broken, {} foreign\n",
        plan.first, plan.last, plan.tasks.size(), total - missing - broken - foreign, missing,
        broken, foreign);
    for (const auto& t : plan.tasks)
        std::cout << taskLine(t, rerun.count(t.index) > 0, readTaskLog(t.log)) << "\n";
    if (rerun.empty()) return 0;
    std::string list;
    for (int i : rerun) list += (list.empty() ? "" : ",") + std::to_string(i);
    std::cout << "re-run tasks " << list << " (Slurm: sbatch --array=" << list
              << " PLAN_SCRIPT; command list: those lines, counted from 0)\n";
    return 1;
}

}  // namespace kestrel::cli
