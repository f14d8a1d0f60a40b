// Ctrl-C during `kestrel run`: the run stops after the frame in progress, exits with 130 (the
// shell's code for SIGINT), and leaves only complete EXR files and no temporary files behind.
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

}  // namespace

TEST(CliInterrupt, SigintStopsCleanlyAfterAFrame) {
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
    ::kill(pid, SIGINT);
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    const std::string text = readText(log);

    ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status) << "\n" << text;
    EXPECT_EQ(WEXITSTATUS(status), 130) << text;
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
