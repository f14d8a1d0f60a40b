#pragma once
// `kestrel farm plan`: a contiguous frame range cut into chunks, each chunk one `kestrel run`
// task with its own --frames, --warmup (history warmed up on the frames before the chunk) and
// --resume (a re-queued task finishes what a failed one started), logging to its own file.
// Written as a Slurm job-array script, an OpenJD job template, a plain command list or JSON
// (docs/farm.md).
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace kestrel::cli {

/// Warm-up frames a chunk runs before its first written frame unless --warmup says otherwise.
/// Measured by scripts/farm-warmup.sh (docs/farm.md has the table and the bound it gives).
constexpr int kDefaultFarmWarmup = 16;

/// What the user asks for (paths as given; makePlan makes them absolute).
struct FarmOptions {
    std::string graph;
    std::vector<std::string> inputs, outputs;  ///< PATTERN or name=PATTERN, as for `run`
    std::vector<std::string> sets;             ///< pass.param=value
    std::vector<std::string> extra;            ///< other `kestrel run` options, passed through
    std::string frames;                        ///< A-B
    std::string cuts;                          ///< camera cuts, as `run --cuts`
    int chunk = 0;
    int warmup = kDefaultFarmWarmup;
    std::string logDir;  ///< default: farm-logs/ beside the first output
};

struct FarmTask {
    int index = 0;
    int64_t first = 0, last = 0;  ///< written frames, inclusive
    int warmup = 0;               ///< never reaches before the shot's first frame or the last cut
    std::string log;              ///< absolute path of the task's log file
};

struct FarmPlan {
    std::string kestrel;  ///< absolute path of the kestrel binary
    std::string graph;
    std::vector<std::string> inputs, outputs, sets, extra;
    std::string cuts;
    int64_t first = 0, last = 0;
    int chunk = 0, warmup = 0;
    std::string logDir;
    std::vector<FarmTask> tasks;

    /// `kestrel run` and the options every task shares (argv, without --frames, --warmup).
    std::vector<std::string> runArgs() const;
    /// The task's `kestrel run` command line (argv, without the log redirection).
    std::vector<std::string> taskArgs(const FarmTask& t) const;
    /// The same as one shell line appending stdout and stderr to the task's log.
    std::string taskCommand(const FarmTask& t) const;
    /// The task writing `frame` (nullptr outside the plan).
    const FarmTask* taskOf(int64_t frame) const;
};

/// Splits the range into tasks. Throws Error naming the option on bad input (usage, exit 2).
FarmPlan makePlan(const FarmOptions& options);

/// A bash script for `sbatch`: `#SBATCH --array=0-K`, SLURM_ARRAY_TASK_ID picks the task.
std::string slurmScript(const FarmPlan& plan);
/// An OpenJD job template (specificationVersion jobtemplate-2023-09, JSON form) for AWS Deadline
/// Cloud or any OpenJD runtime: one step whose CHUNK[INT] task parameter is the shot's range in
/// contiguous chunks of plan.chunk frames. Each task computes the same warm-up as the plan's
/// task and runs `kestrel run --resume --progress openjd`. Throws Error when a path would be
/// read as an OpenJD format string.
nlohmann::json openjdTemplate(const FarmPlan& plan);
/// One shell line per task (for GNU parallel, a shell loop, OpenCue, Deadline).
std::string commandList(const FarmPlan& plan);
nlohmann::json planToJson(const FarmPlan& plan);
/// Reads a plan written by planToJson; throws Error naming `file` and the JSON key.
FarmPlan planFromJson(const nlohmann::json& j, const std::string& file);

/// POSIX shell quoting: the word unchanged when it is safe, else in single quotes.
std::string shellQuote(const std::string& word);

}  // namespace kestrel::cli
