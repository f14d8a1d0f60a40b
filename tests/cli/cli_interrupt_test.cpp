// Ctrl-C (SIGINT) or SIGTERM (Slurm's time limit, Deadline's cancel) during `kestrel run`: the
// run stops after the frame in progress, exits with 130 or 143 (the shell's codes for them), and
// leaves only complete EXR files and no temporary files behind. `--resume` removes the
// temporaries a killed run (kill -9) left.
#include <fcntl.h>

#include "CliRunner.h"
#include "ExrCheck.h"

using namespace clitest;

namespace {

/// Starts `kestrel args...` in `cwd` with stdout/stderr to files; returns the child's pid.
pid_t spawnCli(const fs::path& cwd, const std::vector<std::string>& args, const fs::path& log) {
    pid_t pid = ::fork();
    if (pid != 0) return pid;
    // Child: only async-signal-safe work would be strictly required here; the test process is
    // single-threaded at this point, so plain calls are fine.
    if (::chdir(cwd.c_str()) != 0) ::_exit(127);
    int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) ::_exit(127);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::setenv("KESTREL_PLUGIN_PATH", "", 1);
    std::vector<char*> argv;
    std::string exe = KESTREL_CLI;
    argv.push_back(exe.data());
    std::vector<std::string> copy = args;
    for (auto& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
}

/// Runs slow.json over 200 frames, sends `sig` once the first frame is on disk, and checks the
/// run stopped cleanly with exit code `code`.
void stopsCleanlyOn(int sig, int code) {
    Sandbox box;
    // One 64x48 frame, linked as frames 1..200: a run long enough (three A-Trous passes, one
    // thread) to be interrupted mid-way without rendering 200 frames.
    if (!makeScene(box, box.work() / "scene", 64, 48, 1))
        GTEST_SKIP() << "no scenegen in this build";
    const fs::path noisy = box.work() / "scene" / "noisy";
    for (int f = 2; f <= 200; ++f)
        fs::create_symlink("frame_0001.exr", noisy / frameName("frame_", f, ".exr"));

    const fs::path out = box.work() / "out";
    const fs::path log = box.root() / "interrupt.log";
    pid_t pid = spawnCli(
        box.work(),
        {"run", (graphDir() / "slow.json").string(), "--input", "scene/noisy/frame_####.exr",
         "--output", "out/s.####.exr", "--frames", "1-200", "--threads", "1"},
        log);
    ASSERT_GT(pid, 0);

    // Wait (up to 60 s) for the first frame on disk, then press Ctrl-C.
    bool sawFrame = false;
    int status = 0;
    bool exited = false;
    for (int i = 0; i < 30000 && !sawFrame; ++i) {
        if (::waitpid(pid, &status, WNOHANG) == pid) {
            exited = true;
            break;
        }
        sawFrame = countFiles(out, ".exr") > 0;
        if (!sawFrame) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    ASSERT_FALSE(exited) << "kestrel ended before writing a frame:\n" << readText(log);
    ASSERT_TRUE(sawFrame) << readText(log);
    ::kill(pid, sig);
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    const std::string text = readText(log);

    ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status) << "\n" << text;
    EXPECT_EQ(WEXITSTATUS(status), code) << text;
    EXPECT_NE(text.find("interrupted"), std::string::npos) << text;
    EXPECT_FALSE(looksLikeCrash(text)) << text;

    const int written = countFiles(out, ".exr");
    EXPECT_GE(written, 1);
    EXPECT_LT(written, 200) << "the interrupt did not stop the run";
    for (const auto& e : fs::directory_iterator(out)) {
        RgbImage img;
        std::string why;
        EXPECT_TRUE(readRgb(e.path().string(), img, &why)) << e.path() << ": " << why;
        EXPECT_EQ(img.width, 64);
    }
    EXPECT_EQ(countTempFiles(out), 0) << "temporary files left behind";
    // Frames are written in order and none is skipped: 1..written.
    for (int f = 1; f <= written; ++f)
        EXPECT_TRUE(fs::exists(out / frameName("s.", f, ".exr"))) << f;
}

}  // namespace

TEST(CliInterrupt, SigintStopsCleanlyAfterAFrame) {
    stopsCleanlyOn(SIGINT, 130);
}

TEST(CliInterrupt, SigtermStopsCleanlyAfterAFrame) {
    stopsCleanlyOn(SIGTERM, 143);
}

TEST(CliInterrupt, ResumeRemovesTemporariesOfDeadProcesses) {
    Sandbox box;
    if (!makeScene(box, box.work() / "scene", 32, 24, 3))
        GTEST_SKIP() << "no scenegen in this build";
    // A process that has ended: its pid is what a run killed with kill -9 left in the name.
    const pid_t dead = ::fork();
    if (dead == 0) ::_exit(0);
    ASSERT_EQ(::waitpid(dead, nullptr, 0), dead);
    const fs::path out = box.work() / "out";
    const fs::path stale = out / (".c.0002.exr.tmp-" + std::to_string(dead));
    // A live writer's (this test's own pid): another run may be writing it right now.
    const fs::path live = out / (".c.0003.exr.tmp-" + std::to_string(::getpid()));
    writeText(stale, "half a frame");
    writeText(live, "a frame being written");
    auto r = box.run({"run", (graphDir() / "copy.json").string(), "--input",
                      "scene/noisy/frame_####.exr", "--output", "out/c.####.exr", "--frames", "1-3",
                      "--resume"});
    EXPECT_EQ(r.code, 0) << r.all();
    EXPECT_FALSE(fs::exists(stale)) << r.all();
    EXPECT_TRUE(fs::exists(live)) << r.all();
    EXPECT_NE(r.err.find(stale.filename().string()), std::string::npos) << r.all();
    EXPECT_EQ(countFiles(out, ".exr"), 3);
}
