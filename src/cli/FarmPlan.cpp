#include "FarmPlan.h"

#include <algorithm>
#include <filesystem>

#include "Common.h"
#include "kestrel/Error.h"
#include "kestrel/FramePattern.h"

namespace kestrel::cli {

namespace fs = std::filesystem;

namespace {

/// Absolute, normalised path: tasks run from whatever directory the scheduler picks.
std::string absolutePath(const std::string& p) {
    return fs::absolute(fs::path(p)).lexically_normal().string();
}

/// "PATTERN" or "name=PATTERN" (the rule of Common.cpp's assignPaths) with the pattern absolute.
std::string absoluteSpec(const std::string& spec) {
    auto eq = spec.find('=');
    if (eq != std::string::npos && eq > 0 && spec.find('/') > eq)
        return spec.substr(0, eq + 1) + absolutePath(spec.substr(eq + 1));
    return absolutePath(spec);
}

std::string patternOf(const std::string& spec) {
    auto eq = spec.find('=');
    if (eq != std::string::npos && eq > 0 && spec.find('/') > eq) return spec.substr(eq + 1);
    return spec;
}

std::string kestrelBinary() {
    std::error_code ec;
    fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string("kestrel") : exe.string();
}

std::string rangeText(int64_t a, int64_t b) {
    return a == b ? std::to_string(a) : std::to_string(a) + "-" + std::to_string(b);
}

template <class T>
T required(const nlohmann::json& j, const char* key, const std::string& file) {
    if (!j.contains(key)) throw Error(file + ": farm plan has no \"" + key + "\"");
    try {
        return j.at(key).get<T>();
    } catch (const nlohmann::json::exception&) {
        throw Error(file + ": farm plan key \"" + key + "\" has the wrong type");
    }
}

}  // namespace

std::string shellQuote(const std::string& w) {
    const bool safe = !w.empty() && std::all_of(w.begin(), w.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) ||
               std::string_view("/._-+=,:%@#").find(c) != std::string_view::npos;
    });
    if (safe && w[0] != '#') return w;
    std::string q = "'";
    for (char c : w) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

std::vector<std::string> FarmPlan::runArgs() const {
    std::vector<std::string> a{kestrel, "run", graph};
    for (const auto& s : inputs) a.insert(a.end(), {"--input", s});
    for (const auto& s : outputs) a.insert(a.end(), {"--output", s});
    for (const auto& s : sets) a.insert(a.end(), {"--set", s});
    if (!cuts.empty()) a.insert(a.end(), {"--cuts", cuts});
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
}

std::vector<std::string> FarmPlan::taskArgs(const FarmTask& t) const {
    std::vector<std::string> a = runArgs();
    a.insert(a.end(), {"--frames", rangeText(t.first, t.last), "--warmup", std::to_string(t.warmup),
                       "--resume"});
    return a;
}

std::string FarmPlan::taskCommand(const FarmTask& t) const {
    std::string line;
    for (const auto& w : taskArgs(t)) line += (line.empty() ? "" : " ") + shellQuote(w);
    return line + " >> " + shellQuote(t.log) + " 2>&1";
}

const FarmTask* FarmPlan::taskOf(int64_t frame) const {
    for (const auto& t : tasks)
        if (frame >= t.first && frame <= t.last) return &t;
    return nullptr;
}

FarmPlan makePlan(const FarmOptions& o) {
    if (o.graph.empty()) throw Error("farm: give the GRAPH file");
    if (o.inputs.empty()) throw Error("farm: give --input PATTERN (the frames to denoise)");
    if (o.outputs.empty()) throw Error("farm: give --output PATTERN (where the tasks write)");
    if (o.frames.empty()) throw Error("farm: give --frames A-B (the shot's range)");
    if (o.chunk < 1) throw Error("--chunk " + std::to_string(o.chunk) + ": must be at least 1");
    if (o.warmup < 0) throw Error("--warmup " + std::to_string(o.warmup) + ": must be 0 or more");
    const std::vector<int64_t> frames = parseFrameList(o.frames);
    for (size_t i = 1; i < frames.size(); ++i)
        if (frames[i] != frames[i - 1] + 1)
            throw Error("--frames " + o.frames + ": a farm plan takes one contiguous range A-B");
    std::vector<int64_t> cuts;
    if (!o.cuts.empty()) {
        try {
            cuts = parseFrameRange(o.cuts);
        } catch (const Error& e) {
            throw Error(std::string("--cuts: ") + e.what());
        }
    }

    FarmPlan p;
    p.kestrel = kestrelBinary();
    p.graph = absolutePath(o.graph);
    for (const auto& s : o.inputs) p.inputs.push_back(absoluteSpec(s));
    for (const auto& s : o.outputs) p.outputs.push_back(absoluteSpec(s));
    p.sets = o.sets;
    p.extra = o.extra;
    p.cuts = o.cuts;
    p.first = frames.front();
    p.last = frames.back();
    p.chunk = o.chunk;
    p.warmup = o.warmup;
    p.logDir =
        o.logDir.empty()
            ? (fs::path(absolutePath(patternOf(o.outputs.front()))).parent_path() / "farm-logs")
                  .string()
            : absolutePath(o.logDir);
    int index = 0;
    for (int64_t a = p.first; a <= p.last; a += o.chunk, ++index) {
        FarmTask t;
        t.index = index;
        t.first = a;
        t.last = std::min<int64_t>(p.last, a + o.chunk - 1);
        // The shot's first frames have no history before them in the unsplit run either.
        int64_t start = p.first;  // history before it is not the unsplit run's either
        for (auto c : cuts)
            if (c <= a) start = std::max(start, c);
        t.warmup = int(std::min<int64_t>(o.warmup, a - start));
        char name[32];
        std::snprintf(name, sizeof name, "task-%04d.log", index);
        t.log = (fs::path(p.logDir) / name).string();
        p.tasks.push_back(t);
    }
    return p;
}

std::string slurmScript(const FarmPlan& p) {
    std::string s = "#!/bin/bash\n";
    s += "# kestrel farm plan: " + p.graph + ", frames " + rangeText(p.first, p.last) + " in " +
         std::to_string(p.tasks.size()) + " tasks of " + std::to_string(p.chunk) + " (warm-up " +
         std::to_string(p.warmup) + ").\n";
    s += "# Submit with `sbatch THIS_FILE` (sbatch options on its command line override the ones\n"
         "# below); check with `kestrel farm check` and re-submit failed tasks with --array=I,J.\n";
    s += "#SBATCH --job-name=kestrel-" + fs::path(p.graph).stem().string() + "\n";
    s += "#SBATCH --array=0-" + std::to_string(p.tasks.size() - 1) + "\n";
    s += "#SBATCH --ntasks=1\n";
    s += "#SBATCH --output=" + p.logDir + "/slurm-%A_%a.out\n";
    s += "set -u\n";
    s += "case \"${SLURM_ARRAY_TASK_ID:?submit with sbatch: it sets SLURM_ARRAY_TASK_ID}\" in\n";
    for (const auto& t : p.tasks)
        s += "  " + std::to_string(t.index) + ") exec " + p.taskCommand(t) + " ;;\n";
    s += "  *) echo \"kestrel farm: no task $SLURM_ARRAY_TASK_ID in this plan\" >&2; exit 2 ;;\n";
    s += "esac\n";
    return s;
}

std::string commandList(const FarmPlan& p) {
    std::string s;
    for (const auto& t : p.tasks) s += p.taskCommand(t) + "\n";
    return s;
}

namespace {

/// The task's script (bash, an embedded file of the template; $1 is the chunk "A-B"). The
/// scheduler picks the chunk, so the script derives what makePlan gives that chunk: its warm-up
/// (W frames, never before the shot's first frame or the last cut at or before A) and its log.
std::string openjdTaskScript(const FarmPlan& p) {
    const std::string first = std::to_string(p.first);
    std::string cuts;
    if (!p.cuts.empty())
        for (auto c : parseFrameRange(p.cuts)) cuts += " " + std::to_string(c);
    std::string run;
    for (const auto& w : p.runArgs()) run += shellQuote(w) + " ";
    run += "--frames \"$a-$b\" --warmup \"$warmup\" --resume --progress openjd &\n";

    std::string s = "#!/bin/bash\n";
    s += "# kestrel farm plan --format openjd: one chunk of " + p.graph + ".\n";
    s += "set -euo pipefail\n";
    s += "chunk=${1:?usage: task.sh A-B}\n";
    s += "if [[ ! $chunk =~ ^([0-9]+)-([0-9]+)$ ]]; then\n"
         "  echo \"kestrel farm: chunk '$chunk' is not A-B (rangeConstraint CONTIGUOUS)\" >&2\n"
         "  exit 2\n"
         "fi\n"
         "a=${BASH_REMATCH[1]} b=${BASH_REMATCH[2]}\n";
    // As makePlan: history starts at the shot's first frame or the last cut at or before A.
    s += "start=" + first + "\n";
    s += "for cut in" + cuts + "; do if (( cut <= a && cut > start )); then start=$cut; fi; done\n";
    s += "warmup=$(( a - start ))\n";
    s += "if (( warmup > " + std::to_string(p.warmup) +
         " )); then warmup=" + std::to_string(p.warmup) + "; fi\n";
    // With the default chunking a chunk is plan task (A - first) / chunk: the log `farm check`
    // reads for it.
    s += "log=$(printf '%s/task-%04d.log' " + shellQuote(p.logDir) + " $(( (a - " + first + ") / " +
         std::to_string(p.chunk) + " )))\n";
    s += "mkdir -p " + shellQuote(p.logDir) + "\n";
    // Both to the log and to the worker, which reads the openjd_progress lines.
    s += "exec > >(tee -a \"$log\") 2>&1\n"
         "tee_pid=$!\n";
    // kestrel in the background: a cancel's SIGTERM to this shell is passed on (kestrel finishes
    // the frame in progress), and the task ends only once tee has written everything.
    s += run;
    s += "pid=$!\n"
         "trap 'kill -TERM \"$pid\" 2>/dev/null' TERM INT\n"
         "while :; do\n"
         "  wait \"$pid\" && status=0 || status=$?\n"
         "  kill -0 \"$pid\" 2>/dev/null || break  # wait was cut short by the trap\n"
         "done\n"
         "exec >&- 2>&-\n"
         "wait \"$tee_pid\" || true\n"
         "exit \"$status\"\n";
    return s;
}

}  // namespace

nlohmann::json openjdTemplate(const FarmPlan& p) {
    const std::string script = openjdTaskScript(p);
    // OpenJD reads {{...}} in the script and its arguments as format strings.
    if (script.find("{{") != std::string::npos)
        throw Error(
            "--format openjd: a path or option contains '{{', which OpenJD reads as a "
            "format string; rename it");
    const std::string name =
        "kestrel " + fs::path(p.graph).stem().string() + " " + rangeText(p.first, p.last);
    nlohmann::json frame = {
        {"name", "Frame"},
        {"type", "CHUNK[INT]"},
        {"range", rangeText(p.first, p.last)},
        // No targetRuntimeSeconds: every chunk pays the warm-up, so the plan's chunk size is
        // kept rather than shrunk by the scheduler.
        {"chunks", {{"defaultTaskCount", p.chunk}, {"rangeConstraint", "CONTIGUOUS"}}}};
    nlohmann::json onRun = {
        {"command", "bash"},
        {"args", {"{{Task.File.Run}}", "{{Task.Param.Frame}}"}},
        // kestrel finishes the frame in progress on SIGTERM; NOTIFY_THEN_TERMINATE sends it.
        {"cancelation", {{"mode", "NOTIFY_THEN_TERMINATE"}}}};
    nlohmann::json step = {
        {"name", "Denoise"},
        {"parameterSpace", {{"taskParameterDefinitions", {frame}}}},
        {"script",
         {{"actions", {{"onRun", onRun}}},
          {"embeddedFiles", {{{"name", "Run"}, {"type", "TEXT"}, {"data", script}}}}}}};
    return {{"specificationVersion", "jobtemplate-2023-09"},
            {"extensions", {"TASK_CHUNKING"}},
            {"name", name.substr(0, 128)},  // OpenJD's limit on a job name
            {"steps", {step}}};
}

nlohmann::json planToJson(const FarmPlan& p) {
    nlohmann::json tasks = nlohmann::json::array();
    for (const auto& t : p.tasks)
        tasks.push_back({{"task", t.index},
                         {"first", t.first},
                         {"last", t.last},
                         {"warmup", t.warmup},
                         {"log", t.log},
                         {"argv", p.taskArgs(t)},
                         {"command", p.taskCommand(t)}});
    return {{"kestrelFarmPlan", 1}, {"kestrel", p.kestrel}, {"graph", p.graph},
            {"inputs", p.inputs},   {"outputs", p.outputs}, {"sets", p.sets},
            {"extra", p.extra},     {"cuts", p.cuts},       {"first", p.first},
            {"last", p.last},       {"chunk", p.chunk},     {"warmup", p.warmup},
            {"logDir", p.logDir},   {"tasks", tasks}};
}

FarmPlan planFromJson(const nlohmann::json& j, const std::string& file) {
    if (!j.is_object() || !j.contains("kestrelFarmPlan"))
        throw Error(file + ": not a kestrel farm plan (no \"kestrelFarmPlan\" key)");
    FarmPlan p;
    p.kestrel = required<std::string>(j, "kestrel", file);
    p.graph = required<std::string>(j, "graph", file);
    p.inputs = required<std::vector<std::string>>(j, "inputs", file);
    p.outputs = required<std::vector<std::string>>(j, "outputs", file);
    p.sets = required<std::vector<std::string>>(j, "sets", file);
    p.extra = required<std::vector<std::string>>(j, "extra", file);
    p.cuts = j.value("cuts", std::string());
    p.first = required<int64_t>(j, "first", file);
    p.last = required<int64_t>(j, "last", file);
    p.chunk = required<int>(j, "chunk", file);
    p.warmup = required<int>(j, "warmup", file);
    p.logDir = required<std::string>(j, "logDir", file);
    const auto tasks = required<nlohmann::json>(j, "tasks", file);
    if (!tasks.is_array() || tasks.empty()) throw Error(file + ": farm plan \"tasks\" is empty");
    for (size_t i = 0; i < tasks.size(); ++i) {
        const std::string where = file + " tasks[" + std::to_string(i) + "]";
        FarmTask t;
        t.index = required<int>(tasks[i], "task", where);
        t.first = required<int64_t>(tasks[i], "first", where);
        t.last = required<int64_t>(tasks[i], "last", where);
        t.warmup = required<int>(tasks[i], "warmup", where);
        t.log = required<std::string>(tasks[i], "log", where);
        if (t.first > t.last || t.first < p.first || t.last > p.last)
            throw Error(where + ": frames " + rangeText(t.first, t.last) + " outside the plan's " +
                        rangeText(p.first, p.last));
        p.tasks.push_back(t);
    }
    return p;
}

}  // namespace kestrel::cli
