// kestrel farm plan / check end to end on tiny generated scenes: the plan's tasks (Slurm array,
// command list, JSON), check's missing / broken frames and exit codes, and the warm-up claim of
// docs/farm.md: chunked and unsplit runs agree within the stated bound, and exactly after a
// camera cut inside the warm-up. The Slurm run itself is farm_slurm_test.sh.
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <thread>
#include <tuple>

#include "CliRunner.h"

using namespace clitest;

namespace {

// docs/farm.md: largest relMSE between a chunk and the unsplit run at the default warm-up, over
// the zoo scenes and the public sequences (scripts/farm-warmup.sh). farm_slurm_test uses it too.
constexpr double kWarmupBound = KESTREL_FARM_WARMUP_BOUND;

class Farm : public ::testing::Test {
protected:
    /// Generates zoo scene `name` (48x32, `frames` frames) into scene/.
    bool makeZooScene(const std::string& name, int frames) {
        CliResult r = box.run({"scenegen", "--scene", name, "--out", "scene", "--width", "48",
                               "--height", "32", "--frames", std::to_string(frames), "--spp", "1"});
        return r.code == 0;
    }
    std::vector<std::string> planArgs(const std::string& sub, const std::string& out,
                                      const std::string& frames, int chunk) {
        return {"farm",
                sub,
                (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "svgf.json").string(),
                "--input",
                "scene/noisy/frame_####.exr",
                "--output",
                out + "/frame_####.exr",
                "--frames",
                frames,
                "--chunk",
                std::to_string(chunk),
                "--threads",
                "1"};
    }
    /// Plans as a command list and runs it with bash (what a shell loop on the farm does).
    CliResult planAndRun(std::vector<std::string> args) {
        args.insert(args.end(), {"--format", "commands", "--out", "../tasks.sh"});
        CliResult r = box.run(args);
        if (r.code != 0) return r;
        const std::string cmd = "cd " + quote(box.work().string()) + " && bash ../tasks.sh";
        r.code = WEXITSTATUS(std::system(cmd.c_str()));
        return r;
    }
    CliResult unsplit(const std::string& out, const std::string& frames) {
        return box.run({"run", (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "svgf.json").string(),
                        "--input", "scene/noisy/frame_####.exr", "--output",
                        out + "/frame_####.exr", "--frames", frames, "--threads", "1"});
    }
    /// relMSE of each frame of a/ against b/ (kestrel compare), by frame number.
    std::map<int64_t, double> relMse(const std::string& a, const std::string& b,
                                     const std::string& frames) {
        CliResult r = box.run({"compare", a + "/frame_####.exr", b + "/frame_####.exr", "--frames",
                               frames, "--json"});
        EXPECT_EQ(r.code, 0) << r.all();
        std::map<int64_t, double> m;
        if (r.code != 0) return m;
        const auto j = nlohmann::json::parse(r.out);  // kept: the loop reads into it
        for (const auto& f : j["frames"]) m[f["frame"].get<int64_t>()] = f["relMse"].get<double>();
        return m;
    }
    Sandbox box;
};

}  // namespace

TEST_F(Farm, PlanWritesOneTaskPerChunkInEveryFormat) {
    auto args = planArgs("plan", "out", "1-10", 4);
    args.insert(args.end(), {"--warmup", "3", "--set", "taa.alpha=0.2"});
    CliResult slurm = box.run(args);
    ASSERT_EQ(slurm.code, 0) << slurm.all();
    EXPECT_NE(slurm.out.find("\n#SBATCH --array=0-2\n"), std::string::npos) << slurm.out;
    EXPECT_NE(slurm.out.find("case \"${SLURM_ARRAY_TASK_ID"), std::string::npos) << slurm.out;
    const std::string abs = box.work().string();
    // Task 2: frames 9-10, warm-up 3, resumable, absolute paths, its own log, the --set kept.
    const std::regex task2("\n  2\\) exec /\\S+/kestrel run /\\S+/graphs/svgf.json --input " + abs +
                           "/scene/noisy/frame_####.exr --output " + abs +
                           "/out/frame_####.exr --set taa.alpha=0.2 --threads 1 --frames 9-10 "
                           "--warmup 3 --resume >> " +
                           abs + "/out/farm-logs/task-0002.log 2>&1 ;;");
    EXPECT_TRUE(std::regex_search(slurm.out, task2)) << slurm.out;
    EXPECT_TRUE(fs::is_directory(box.work() / "out" / "farm-logs"));

    args.insert(args.end(), {"--format", "commands"});
    CliResult cmds = box.run(args);
    ASSERT_EQ(cmds.code, 0) << cmds.all();
    EXPECT_EQ(std::count(cmds.out.begin(), cmds.out.end(), '\n'), 3) << cmds.out;
    EXPECT_NE(cmds.out.find("--frames 1-4 --warmup 0 --resume"), std::string::npos) << cmds.out;
    EXPECT_NE(cmds.out.find("--frames 5-8 --warmup 3 --resume"), std::string::npos) << cmds.out;

    args.back() = "json";
    CliResult json = box.run(args);
    ASSERT_EQ(json.code, 0) << json.all();
    const auto j = nlohmann::json::parse(json.out);
    ASSERT_EQ(j["tasks"].size(), 3u);
    // The first chunk has no frames before the shot to warm up on; the others take W = 3.
    EXPECT_EQ(j["tasks"][0]["warmup"], 0);
    EXPECT_EQ(j["tasks"][1]["warmup"], 3);
    EXPECT_EQ(j["tasks"][2]["first"], 9);
    EXPECT_EQ(j["tasks"][2]["last"], 10);
}

TEST_F(Farm, PlanRefusesBadOptionsWithExitTwo) {
    struct Case {
        std::string frames;
        std::vector<std::string> extra;
        std::string text;  // in the error line
    };
    for (const auto& c : std::vector<Case>{{"1-4,8-9", {}, "one contiguous range"},
                                           {"1-10", {"--chunk", "0"}, "--chunk"},
                                           {"1-10", {"--cuts", "x"}, "--cuts"},
                                           {"1-10", {"--thread", "2"}, "kestrel run"}}) {
        auto args = planArgs("plan", "out", c.frames, 4);
        args.insert(args.end(), c.extra.begin(), c.extra.end());
        const std::string& text = c.text;
        CliResult r = box.run(args);
        EXPECT_EQ(r.code, 2) << r.all();
        ASSERT_EQ(r.errorLines().size(), 1u) << r.all();
        EXPECT_NE(r.errorLines()[0].find(text), std::string::npos) << r.errorLines()[0];
        EXPECT_FALSE(looksLikeCrash(r.all()));
    }
}

TEST_F(Farm, CheckNamesMissingAndBrokenFramesAndTheTasksToRerun) {
    if (!makeZooScene("room", 9)) GTEST_SKIP() << "no scenegen in this build";
    auto plan = planArgs("plan", "out", "1-9", 3);
    ASSERT_EQ(planAndRun(plan).code, 0);
    auto jsonPlan = plan;
    jsonPlan.insert(jsonPlan.end(), {"--format", "json", "--out", "../plan.json"});
    ASSERT_EQ(box.run(jsonPlan).code, 0);

    auto checkArgs = planArgs("check", "out", "1-9", 3);
    CliResult ok = box.run(checkArgs);
    EXPECT_EQ(ok.code, 0) << ok.all();
    EXPECT_NE(ok.out.find("9 complete, 0 missing, 0 broken"), std::string::npos) << ok.out;
    // Each task's wall time, from the "run finished" line of its log.
    EXPECT_TRUE(std::regex_search(
        ok.out,
        std::regex("task 2 +frames 7-9 +complete +wall [0-9.]+ s, 3 frames written, exit 0")))
        << ok.out;

    fs::remove(box.work() / "out" / "frame_0002.exr");
    fs::resize_file(box.work() / "out" / "frame_0008.exr", 300);  // a write cut short
    for (const auto& args :
         {checkArgs, std::vector<std::string>{"farm", "check", "--plan", "../plan.json"}}) {
        CliResult bad = box.run(args);
        EXPECT_EQ(bad.code, 1) << bad.all();
        EXPECT_NE(bad.out.find("missing frame 2: " + box.work().string() +
                               "/out/frame_0002.exr (task 0)"),
                  std::string::npos)
            << bad.out;
        EXPECT_NE(bad.out.find("broken  frame 8: "), std::string::npos) << bad.out;
        EXPECT_NE(bad.out.find("7 complete, 1 missing, 1 broken"), std::string::npos) << bad.out;
        EXPECT_NE(bad.out.find("re-run tasks 0,2 "), std::string::npos) << bad.out;
        EXPECT_TRUE(std::regex_search(bad.out, std::regex("task 1 +frames 4-6 +complete")))
            << bad.out;
    }
    // Running the same tasks again (a re-queue) finishes them: --resume writes what is missing.
    const std::string rerun = "cd " + quote(box.work().string()) + " && bash ../tasks.sh";
    ASSERT_EQ(WEXITSTATUS(std::system(rerun.c_str())), 0);
    CliResult fixed = box.run(checkArgs);
    EXPECT_EQ(fixed.code, 0) << fixed.all();
    EXPECT_TRUE(std::regex_search(fixed.out,
                                  std::regex("task 1 .* 0 frames written, exit 0 \\(attempt 2\\)")))
        << fixed.out;
    // A bit flipped inside a chunk (every chunk's size still right) is broken too.
    std::string bytes = readText(box.work() / "out" / "frame_0005.exr");
    bytes[bytes.size() - 9] ^= 0x10;
    writeText(box.work() / "out" / "frame_0005.exr", bytes);
    CliResult flipped = box.run(checkArgs);
    EXPECT_EQ(flipped.code, 1) << flipped.all();
    EXPECT_NE(flipped.out.find("broken  frame 5: "), std::string::npos) << flipped.out;
}

TEST_F(Farm, CheckNamesFramesOfAnotherGraphOrOtherParameters) {
    if (!makeZooScene("room", 6)) GTEST_SKIP() << "no scenegen in this build";
    ASSERT_EQ(planAndRun(planArgs("plan", "out", "1-6", 3)).code, 0);
    const auto checkArgs = planArgs("check", "out", "1-6", 3);
    ASSERT_EQ(box.run(checkArgs).code, 0);
    // Frame 2 from a run with another parameter, frame 5 from another graph: intact EXRs that
    // are not the plan's output (what --resume runs again).
    const std::string graphs = (fs::path(KESTREL_SOURCE_DIR) / "graphs").string();
    const std::string in = (box.work() / "scene" / "noisy" / "frame_####.exr").string();
    const std::string out = (box.work() / "out" / "frame_####.exr").string();
    for (const auto& [graph, extra, frame] :
         {std::tuple{"svgf.json", std::vector<std::string>{"--set", "single.sigmaL=6"}, "2"},
          std::tuple{"svgf-fast.json", std::vector<std::string>{}, "5"}}) {
        std::vector<std::string> args = {"run", graphs + "/" + graph, "--input", in, "--output",
                                         out,   "--frames",           frame};
        args.insert(args.end(), extra.begin(), extra.end());
        CliResult r = box.run(args);
        ASSERT_EQ(r.code, 0) << r.all();
    }
    CliResult r = box.run(checkArgs);
    EXPECT_EQ(r.code, 1) << r.all();
    EXPECT_TRUE(std::regex_search(
        r.out, std::regex("foreign frame 2: \\S+/out/frame_0002.exr \\(written by another graph "
                          "or other parameters: single.atrous0.sigmaL 6.0 \\(the plan's: 4.0\\), "
                          "single.atrous1.sigmaL 6.0 \\(the plan's: 4.0\\)\\) \\(task 0\\)")))
        << r.out;
    EXPECT_TRUE(std::regex_search(
        r.out, std::regex("foreign frame 5: \\S+/out/frame_0005.exr \\(written by another graph "
                          "or other parameters: graph '\\S+' \\(the plan's: 'svgf'\\)\\) "
                          "\\(task 1\\)")))
        << r.out;
    EXPECT_NE(r.out.find("4 complete, 0 missing, 0 broken, 2 foreign"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("re-run tasks 0,1 "), std::string::npos) << r.out;
}

TEST_F(Farm, CheckWithoutAPlanIsAUsageError) {
    CliResult r = box.run({"farm", "check", "--plan", "nothing.json"});
    EXPECT_EQ(r.code, 2) << r.all();
    ASSERT_EQ(r.errorLines().size(), 1u) << r.all();
    EXPECT_NE(r.errorLines()[0].find("nothing.json"), std::string::npos) << r.all();
}

TEST_F(Farm, ChunksAgreeWithTheUnsplitRunWithinTheStatedBound) {
    // The street (glossy surfaces, disocclusion, sky, a moving camera), 30 frames in chunks of
    // 20 at the default warm-up: the second chunk's history starts at frame 5, not 1.
    if (!makeZooScene("street", 30)) GTEST_SKIP() << "no scenegen in this build";
    ASSERT_EQ(planAndRun(planArgs("plan", "chunked", "1-30", 20)).code, 0);
    ASSERT_EQ(unsplit("unsplit", "1-30").code, 0);
    const auto e = relMse("chunked", "unsplit", "1-30");
    ASSERT_EQ(e.size(), 30u);
    for (const auto& [frame, err] : e) {
        if (frame <= 20)
            EXPECT_EQ(err, 0.0) << "frame " << frame << ": the first chunk is the unsplit run";
        else
            EXPECT_LE(err, kWarmupBound) << "frame " << frame;
    }
    EXPECT_GT(e.at(21), 0.0) << "the chunk's history is the unsplit run's: nothing is measured";
}

TEST_F(Farm, CameraCutInsideTheWarmupMakesChunksIdenticalAfterIt) {
    // room-cut jumps to another viewpoint at frame 7 (--cuts 7: history is reset there). The
    // second chunk starts at 9 and would warm up from 5; the cut lies inside that warm-up, so
    // from 7 on both runs compute the same frames: bit-identical outputs, whatever W.
    if (!makeZooScene("room-cut", 12)) GTEST_SKIP() << "no scenegen in this build";
    ASSERT_EQ(
        box.run({"run", (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "svgf.json").string(), "--input",
                 "scene/noisy/frame_####.exr", "--output", "unsplit/frame_####.exr", "--frames",
                 "1-12", "--threads", "1", "--cuts", "7"})
            .code,
        0);
    // The plan starts the warm-up at the cut (2 frames, not 4) ...
    auto args = planArgs("plan", "planned", "1-12", 8);
    args.insert(args.end(), {"--warmup", "4", "--cuts", "7"});
    ASSERT_EQ(planAndRun(args).code, 0);
    EXPECT_NE(readText(box.work() / "../tasks.sh").find("--frames 9-12 --warmup 2 --resume"),
              std::string::npos);
    // ... and a task warmed up across the cut (frames 5-8, as `run --warmup 4`) is the same.
    ASSERT_EQ(box.run({"run", (fs::path(KESTREL_SOURCE_DIR) / "graphs" / "svgf.json").string(),
                       "--input", "scene/noisy/frame_####.exr", "--output", "across/frame_####.exr",
                       "--frames", "9-12", "--warmup", "4", "--threads", "1", "--cuts", "7"})
                  .code,
              0);
    for (const char* chunked : {"planned", "across"}) {
        const auto e = relMse(chunked, "unsplit", "9-12");
        ASSERT_EQ(e.size(), 4u);
        for (const auto& [frame, err] : e) EXPECT_EQ(err, 0.0) << chunked << " frame " << frame;
    }
}

TEST_F(Farm, TaskCommandsSurviveTheShellWithSpacesAndQuotesInPaths) {
    if (!makeZooScene("room", 4)) GTEST_SKIP() << "no scenegen in this build";
    const std::string out = "it's a shot/out";  // a space and a single quote
    auto args = planArgs("plan", out, "1-4", 2);
    ASSERT_EQ(planAndRun(args).code, 0);
    EXPECT_EQ(countFiles(box.work() / out, ".exr"), 4);
    CliResult r = box.run(planArgs("check", out, "1-4", 2));
    EXPECT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.out.find("4 complete, 0 missing, 0 broken"), std::string::npos) << r.out;
}

namespace {

/// Every {{...}} format string of an OpenJD template's strings, recursively.
void formatStrings(const nlohmann::json& j, std::set<std::string>& found) {
    if (j.is_string()) {
        const std::string s = j.get<std::string>();
        const std::regex ref("\\{\\{\\s*([^}]*?)\\s*\\}\\}");
        for (std::sregex_iterator it(s.begin(), s.end(), ref), end; it != end; ++it)
            found.insert((*it)[1].str());
    } else if (j.is_structured()) {
        for (const auto& v : j) formatStrings(v, found);
    }
}

}  // namespace

TEST_F(Farm, OpenjdTemplateRunsEachChunkAsThePlansTaskWithProgressLines) {
    if (!makeZooScene("room", 9)) GTEST_SKIP() << "no scenegen in this build";
    // Chunks 1-3, 4-6, 7-9; warm-ups 0, 3 and 2 (the cut at 5 caps the last one).
    auto args = planArgs("plan", "openjd", "1-9", 3);
    args.insert(args.end(), {"--warmup", "3", "--cuts", "5"});
    auto tmpl = args;
    tmpl.insert(tmpl.end(), {"--format", "openjd", "--out", "../template.json"});
    CliResult r = box.run(tmpl);
    ASSERT_EQ(r.code, 0) << r.all();
    const auto j = nlohmann::json::parse(readText(box.root() / "template.json"));

    // The keys OpenJD requires, and the chunked parameter space.
    EXPECT_EQ(j.at("specificationVersion"), "jobtemplate-2023-09");
    EXPECT_EQ(j.at("extensions"), nlohmann::json::array({"TASK_CHUNKING"}));
    ASSERT_TRUE(j.at("name").is_string());
    EXPECT_FALSE(j["name"].get<std::string>().empty());
    EXPECT_LE(j["name"].get<std::string>().size(), 128u);
    ASSERT_EQ(j.at("steps").size(), 1u);
    const auto& step = j["steps"][0];
    EXPECT_TRUE(step.at("name").is_string());
    const auto& params = step.at("parameterSpace").at("taskParameterDefinitions");
    ASSERT_EQ(params.size(), 1u);
    EXPECT_EQ(params[0].at("name"), "Frame");
    EXPECT_EQ(params[0].at("type"), "CHUNK[INT]");
    EXPECT_EQ(params[0].at("range"), "1-9");
    EXPECT_EQ(params[0].at("chunks").at("defaultTaskCount"), 3);
    EXPECT_EQ(params[0].at("chunks").at("rangeConstraint"), "CONTIGUOUS");
    const auto& onRun = step.at("script").at("actions").at("onRun");
    EXPECT_EQ(onRun.at("command"), "bash");
    EXPECT_EQ(onRun.at("args"),
              nlohmann::json::array({"{{Task.File.Run}}", "{{Task.Param.Frame}}"}));
    const auto& files = step["script"].at("embeddedFiles");
    ASSERT_EQ(files.size(), 1u);
    EXPECT_EQ(files[0].at("name"), "Run");
    EXPECT_EQ(files[0].at("type"), "TEXT");
    // Only the step's own file and parameter are referenced: nothing OpenJD cannot resolve.
    std::set<std::string> refs;
    formatStrings(j, refs);
    EXPECT_EQ(refs, (std::set<std::string>{"Task.File.Run", "Task.Param.Frame"}));

    // What a worker does with each chunk (CONTIGUOUS chunks come as "A-B"): write the embedded
    // file and run the command on it.
    const fs::path script = box.root() / "task.sh";
    writeText(script, files[0]["data"].get<std::string>());
    auto runChunk = [&](const std::string& chunk, std::string& out) {
        const fs::path o = box.root() / "chunk.out";
        const std::string cmd = "cd " + quote(box.work().string()) +
                                " && env KESTREL_PLUGIN_PATH= " + "bash " + quote(script.string()) +
                                " " + quote(chunk) + " >" + quote(o.string()) + " 2>&1 </dev/null";
        const int status = std::system(cmd.c_str());
        out = readText(o);
        return WEXITSTATUS(status);
    };
    const std::map<std::string, int> warmups{{"1-3", 0}, {"4-6", 3}, {"7-9", 2}};
    for (const auto& [chunk, warmup] : warmups) {
        std::string out;
        ASSERT_EQ(runChunk(chunk, out), 0) << chunk << ":\n" << out;
        // One progress line a frame run (warm-up included), ending at 100 %.
        const std::regex progress("(^|\n)openjd_progress: ([0-9.]+)\n");
        std::vector<double> values;
        for (std::sregex_iterator it(out.begin(), out.end(), progress), end; it != end; ++it)
            values.push_back(std::stod((*it)[2].str()));
        ASSERT_EQ(values.size(), size_t(3 + warmup)) << chunk << ":\n" << out;
        EXPECT_DOUBLE_EQ(values.back(), 100.0) << out;
        EXPECT_TRUE(std::is_sorted(values.begin(), values.end())) << out;
        // The plan's warm-up for this chunk: the run logs each warm-up frame as such.
        const std::regex warm("frame [0-9]+ \\([0-9]+/[0-9]+\\) warm-up:");
        EXPECT_EQ(std::distance(std::sregex_iterator(out.begin(), out.end(), warm),
                                std::sregex_iterator()),
                  warmup)
            << chunk << ":\n"
            << out;
    }
    std::string bad;
    EXPECT_EQ(runChunk("1,3", bad), 2) << bad;
    EXPECT_NE(bad.find("not A-B"), std::string::npos) << bad;

    // `farm check` finds every frame and each chunk's log under the plan's task number; the
    // frames are those of the same plan run as a command list.
    auto check = planArgs("check", "openjd", "1-9", 3);
    check.insert(check.end(), {"--warmup", "3", "--cuts", "5"});
    CliResult ok = box.run(check);
    EXPECT_EQ(ok.code, 0) << ok.all();
    EXPECT_TRUE(std::regex_search(
        ok.out, std::regex("task 2 +frames 7-9 +complete +wall [0-9.]+ s, 3 frames written")))
        << ok.out;
    auto commands = planArgs("plan", "commands", "1-9", 3);
    commands.insert(commands.end(), {"--warmup", "3", "--cuts", "5"});
    ASSERT_EQ(planAndRun(commands).code, 0);
    const auto e = relMse("openjd", "commands", "1-9");
    ASSERT_EQ(e.size(), 9u);
    for (const auto& [frame, err] : e) EXPECT_EQ(err, 0.0) << "frame " << frame;
}

TEST_F(Farm, OpenjdRefusesAPathOpenjdWouldReadAsAFormatString) {
    auto args = planArgs("plan", "shot{{1}}", "1-4", 2);
    args.insert(args.end(), {"--format", "openjd"});
    CliResult r = box.run(args);
    EXPECT_EQ(r.code, 2) << r.all();
    ASSERT_EQ(r.errorLines().size(), 1u) << r.all();
    EXPECT_NE(r.errorLines()[0].find("'{{', which OpenJD reads as a format string"),
              std::string::npos)
        << r.errorLines()[0];
    EXPECT_TRUE(r.out.empty()) << r.out;
}

// Cancelling an OpenJD task (NOTIFY_THEN_TERMINATE) sends SIGTERM to the task's process: the
// embedded script passes it on, kestrel finishes the frame in progress, and the task exits 143
// with every written frame complete and the log saying so.
TEST_F(Farm, OpenjdTaskPassesSigtermOnToKestrel) {
    // One 64x48 frame linked as frames 1..200 through slow.json (three A-Trous passes, one
    // thread): long enough to be cancelled mid-way.
    if (!makeZooScene("room", 1)) GTEST_SKIP() << "no scenegen in this build";
    const fs::path noisy = box.work() / "scene" / "noisy";
    for (int f = 2; f <= 200; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%04d.exr", f);
        fs::create_symlink("frame_0001.exr", noisy / name);
    }
    CliResult plan = box.run(
        {"farm", "plan", (fs::path(KESTREL_SOURCE_DIR) / "tests/cli/graphs/slow.json").string(),
         "--input", "scene/noisy/frame_####.exr", "--output", "out/frame_####.exr", "--frames",
         "1-200", "--chunk", "200", "--threads", "1", "--format", "openjd", "--out", "../t.json"});
    ASSERT_EQ(plan.code, 0) << plan.all();
    const auto j = nlohmann::json::parse(readText(box.root() / "t.json"));
    const fs::path script = box.root() / "task.sh", log = box.root() / "task.out";
    writeText(script, j["steps"][0]["script"]["embeddedFiles"][0]["data"].get<std::string>());

    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {  // the worker's process for the task: bash SCRIPT CHUNK
        if (::chdir(box.work().c_str()) != 0) ::_exit(127);
        std::FILE* f = std::freopen(log.c_str(), "w", stdout);
        if (!f || ::dup2(1, 2) < 0) ::_exit(127);
        ::setenv("KESTREL_PLUGIN_PATH", "", 1);
        ::execlp("bash", "bash", script.c_str(), "1-200", static_cast<char*>(nullptr));
        ::_exit(127);
    }
    const fs::path out = box.work() / "out";
    int status = 0;
    bool exited = false;
    for (int i = 0; i < 30000 && countFiles(out, ".exr") == 0; ++i) {
        if (::waitpid(pid, &status, WNOHANG) == pid) {
            exited = true;
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    ASSERT_FALSE(exited) << "the task ended before writing a frame:\n" << readText(log);
    ::kill(pid, SIGTERM);  // the shell only, as a worker signals the process it started
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    const std::string text = readText(log);
    ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status) << "\n" << text;
    EXPECT_EQ(WEXITSTATUS(status), 143) << text;
    EXPECT_NE(text.find("interrupted (SIGTERM)"), std::string::npos) << text;
    EXPECT_NE(text.find("run finished: exit 143"), std::string::npos) << text;
    const int written = countFiles(out, ".exr");
    EXPECT_GE(written, 1);
    EXPECT_LT(written, 200) << "the cancel did not reach kestrel";
}
