// kestrel farm plan / check: cut a shot into chunked `kestrel run` tasks for a render farm, and
// check that every frame they were to write is there and complete (docs/farm.md).
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "Commands.h"
#include "Common.h"
#include "FarmCheck.h"
#include "FarmPlan.h"
#include "OutputSafety.h"
#include "kestrel/Error.h"
#include "kestrel/FramePattern.h"
#include "kestrel/InputFiles.h"

namespace kestrel::cli {

namespace fs = std::filesystem;

namespace {

struct FarmArgs {
    FarmOptions plan;
    std::string format = "slurm";
    std::string out;       // plan: file to write (default: stdout)
    std::string planFile;  // check: a JSON plan instead of the options
};

void addPlanOptions(CLI::App* cmd, FarmArgs& a) {
    cmd->add_option("GRAPH", a.plan.graph, "Graph JSON file");
    cmd->add_option("--input", a.plan.inputs, "Input frames: PATTERN or name=PATTERN (as for run)")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--output", a.plan.outputs, "Output frames: PATTERN or name=PATTERN")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--frames", a.plan.frames, "The shot's range A-B");
    cmd->add_option("--cuts", a.plan.cuts,
                    "Camera cuts (as for run): each task resets history there, and a warm-up "
                    "starts no earlier than the last cut before its chunk");
    cmd->add_option("--chunk", a.plan.chunk, "Frames written per task")
        ->check(CLI::Range(1, 1000000));
    cmd->add_option("--warmup", a.plan.warmup,
                    "Frames each task runs before its chunk without writing (default " +
                        std::to_string(kDefaultFarmWarmup) + ", measured: docs/farm.md)")
        ->check(CLI::Range(0, 100000));
    cmd->add_option("--set", a.plan.sets, "Override a parameter: pass.param=value (repeatable)")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option(
        "--log-dir", a.plan.logDir,
        "Folder of the task logs task-NNNN.log (default: farm-logs/ beside the output)");
    // Anything else is a `kestrel run` option (--threads 8, --skip-bad-frames) given to each task.
    cmd->allow_extras();
}

/// Checks the pass-through options with `kestrel run`'s own parser, so a typo is caught at plan
/// time and not on the farm. Throws Error naming the option.
void checkRunOptions(const FarmOptions& o) {
    CLI::App runApp{"kestrel run", "kestrel"};
    Action unused;
    addRunCommand(runApp, unused);
    std::vector<std::string> words{"kestrel", "run", "graph.json"};
    words.insert(words.end(), o.extra.begin(), o.extra.end());
    std::vector<char*> argv;
    for (auto& w : words) argv.push_back(w.data());
    try {
        runApp.parse(int(argv.size()), argv.data());
    } catch (const CLI::ParseError& e) {
        throw Error("farm: an option passed through to kestrel run is not valid: " +
                    std::string(e.what()));
    }
}

/// The extras CLI11 left over, without --resume (every task resumes anyway).
std::vector<std::string> passThrough(const CLI::App* cmd) {
    std::vector<std::string> extra;
    for (const auto& w : cmd->remaining())
        if (w != "--resume") extra.push_back(w);
    return extra;
}

/// The plan file is never a file the plan's tasks read: the graph, its includes, an input frame.
void checkPlanOut(const FarmPlan& plan, const std::string& out) {
    FilesRead read;
    read.addGraph(loadGraphFile(plan.graph));
    for (const auto& spec : plan.inputs) {
        const auto eq = spec.find('=');  // name=PATTERN, as `kestrel run --input` reads it
        const FramePattern p(
            eq != std::string::npos && eq > 0 && spec.find('/') > eq ? spec.substr(eq + 1) : spec);
        for (int64_t f = std::max<int64_t>(plan.first - plan.warmup, 0); f <= plan.last; ++f) {
            read.add(p.expand(f), "--input");
            if (!p.hasFrameToken()) break;
        }
    }
    read.check(out, "--out", "give another --out");
}

/// Every task of a plan would fail alike on the farm, after queueing, when the graph does not
/// load or validate with the plan's --input/--output/--set, or writes a file it reads (the
/// output pattern equal to the input's): refused now, as `run` would. The graph is validated
/// without opening the frames: a plan may be made before the render has written them.
void checkPlanRuns(const FarmPlan& plan) {
    auto plugins = loadPlugins();
    GraphOptions go;
    go.graph = plan.graph;
    go.inputs = plan.inputs;
    go.outputs = plan.outputs;
    go.sets = plan.sets;
    const GraphDesc desc = prepareGraph(go, plugins->registry);
    CompileOptions opt;
    opt.validateOnly = true;
    opt.firstFrame = plan.first;
    compileGraph(desc, plugins->registry, opt);
    RunFrames frames;
    for (int64_t f = std::max<int64_t>(plan.first - plan.warmup, 0); f <= plan.last; ++f) {
        frames.read.push_back(f);
        if (f >= plan.first) frames.written.push_back(f);
    }
    checkOutputsAreSafe(desc, plugins->registry, frames, "");
}

int planCommand(FarmArgs a) {
    checkRunOptions(a.plan);
    const FarmPlan plan = makePlan(a.plan);
    checkPlanRuns(plan);
    if (!a.out.empty()) checkPlanOut(plan, a.out);
    std::string text;
    if (a.format == "slurm")
        text = slurmScript(plan);
    else if (a.format == "commands")
        text = commandList(plan);
    else if (a.format == "openjd")
        text = openjdTemplate(plan).dump(2) + "\n";
    else
        text = planToJson(plan).dump(2) + "\n";
    std::error_code ec;
    fs::create_directories(plan.logDir, ec);  // tasks append to their logs; Slurm opens --output
    if (ec) throw Error("--log-dir " + plan.logDir + ": cannot create it: " + ec.message());
    if (a.out.empty()) {
        std::cout << text;
    } else {
        std::ofstream f(a.out);
        f << text;
        f.close();
        if (!f) throw Error("--out " + a.out + ": cannot write the plan");
        if (a.format == "slurm")
            fs::permissions(a.out, fs::perms::owner_exec | fs::perms::group_exec,
                            fs::perm_options::add, ec);
    }
    // What the warm-up costs: frames run without being written, against the shot's length.
    int64_t extra = 0;
    for (const auto& t : plan.tasks) extra += t.warmup;
    const int64_t shot = plan.last - plan.first + 1;
    std::cerr << "farm plan: frames " << plan.first << "-" << plan.last << " in "
              << plan.tasks.size() << " tasks of " << plan.chunk << ", warm-up " << plan.warmup
              << " (" << extra << " frames run twice, " << (100 * extra + shot / 2) / shot
              << "% more), logs in " << plan.logDir << "\n";
    return 0;
}

int checkCommand(FarmArgs a) {
    FarmPlan plan;
    if (!a.planFile.empty()) {
        // A plan is a few hundred bytes a task.
        const std::string text = readRegularFile(a.planFile, "--plan", 64u << 20);
        checkJsonText(text, "--plan " + a.planFile);
        nlohmann::json j;
        try {
            j = nlohmann::json::parse(text);
        } catch (const nlohmann::json::exception& e) {
            throw Error("--plan " + a.planFile + ": not JSON: " + e.what());
        }
        plan = planFromJson(j, a.planFile);
    } else {
        plan = makePlan(a.plan);
    }
    return checkPlan(plan);
}

}  // namespace

void addFarmCommand(CLI::App& app, Action& action) {
    auto* farm = app.add_subcommand(
        "farm", "Plan a shot as chunked tasks for a render farm, check the result");
    farm->require_subcommand(1);

    auto planArgs = std::make_shared<FarmArgs>();
    auto* plan = farm->add_subcommand(
        "plan",
        "Split --frames A-B into tasks of --chunk frames (Slurm array, OpenJD job template, "
        "command list, JSON)");
    addPlanOptions(plan, *planArgs);
    plan->footer(
        "Other options are kestrel run options, given to every task (--threads 8, "
        "--skip-bad-frames). docs/farm.md has examples.");
    plan->add_option("--format", planArgs->format,
                     "slurm (sbatch script), openjd (OpenJD job template, JSON form), commands, "
                     "json")
        ->check(CLI::IsMember({"slurm", "openjd", "commands", "json"}));
    plan->add_option("--out", planArgs->out, "Write the plan to this file (default: stdout)");
    plan->callback([&action, planArgs, plan] {
        planArgs->plan.extra = passThrough(plan);
        action = [planArgs] { return exitTwoOnUsageError([&] { return planCommand(*planArgs); }); };
    });

    auto checkArgs = std::make_shared<FarmArgs>();
    auto* check = farm->add_subcommand("check",
                                       "Every frame of a plan written and complete? Exit 0 yes, 1 "
                                       "missing or broken frames, 2 usage");
    addPlanOptions(check, *checkArgs);
    check->add_option("--plan", checkArgs->planFile, "A plan written with --format json");
    check->callback([&action, checkArgs, check] {
        checkArgs->plan.extra = passThrough(check);
        action = [checkArgs] {
            return exitTwoOnUsageError([&] { return checkCommand(*checkArgs); });
        };
    });
}

}  // namespace kestrel::cli
