#pragma once
// Helpers for end-to-end tests of the kestrel command line: a private temporary folder per test,
// running the CLI (KESTREL_CLI) in it with stdout, stderr and the exit code captured, and a tiny
// generated scene to feed graphs.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace clitest {

namespace fs = std::filesystem;

struct CliResult {
    int code = -1;    ///< exit status; 128 + signal if the CLI was killed
    std::string out;  ///< standard output
    std::string err;  ///< standard error
    std::string all() const { return "--- stdout:\n" + out + "--- stderr:\n" + err; }
    /// Lines of stderr that start with "error:".
    std::vector<std::string> errorLines() const {
        std::vector<std::string> lines;
        std::istringstream s(err);
        for (std::string l; std::getline(s, l);)
            if (l.rfind("error:", 0) == 0) lines.push_back(l);
        return lines;
    }
};

inline std::string readText(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

inline void writeText(const fs::path& p, const std::string& text) {
    fs::create_directories(p.parent_path());
    std::ofstream f(p, std::ios::binary);
    f << text;
}

inline std::string quote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

/// Whether any output shows a crash, an uncaught exception or a sanitizer report.
inline bool looksLikeCrash(const std::string& text) {
    for (const char* s : {"terminate called", "what():", "Segmentation fault", "Aborted",
                          "core dumped", "AddressSanitizer", "runtime error:", "stack trace"})
        if (text.find(s) != std::string::npos) return true;
    return false;
}

/// A fresh temporary folder, removed with its contents at the end of the test. The CLI runs in
/// work(); its captured output goes beside it so it never pollutes the outputs a test counts.
class Sandbox {
public:
    Sandbox() {
        std::string tmpl = (fs::temp_directory_path() / "kestrel-cli-test.XXXXXX").string();
        if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
        root_ = tmpl;
        fs::create_directories(work());
    }
    ~Sandbox() {
        std::error_code ec;
        fs::remove_all(root_, ec);
    }
    Sandbox(const Sandbox&) = delete;
    Sandbox& operator=(const Sandbox&) = delete;

    const fs::path& root() const { return root_; }
    fs::path work() const { return root_ / "work"; }

    /// Runs `kestrel <args>` in work() with KESTREL_PLUGIN_PATH cleared (only the build's own
    /// plugins), plus `env` ("NAME=value ..."), and captures everything.
    /// Safe to call from several threads at once (tests of concurrent runs).
    CliResult run(const std::vector<std::string>& args, const std::string& env = "") {
        return runLimited(args, env, "");
    }
    /// run() under `timeout SECONDS` and an address-space limit (4 GB unless `kilobytes` says):
    /// for inputs that once made the CLI read forever, so a regression fails the test instead of
    /// hanging the machine, and for what the CLI does when memory runs out.
    CliResult runWithin(int seconds, const std::vector<std::string>& args,
                        long kilobytes = 4000000) {
        return runLimited(args, "",
                          "ulimit -v " + std::to_string(kilobytes) + " && timeout -s KILL " +
                              std::to_string(seconds) + " ");
    }

private:
    CliResult runLimited(const std::vector<std::string>& args, const std::string& env,
                         const std::string& prefix) {
        const int id = runs_++;
        const fs::path out = root_ / ("run" + std::to_string(id) + ".out");
        const fs::path err = root_ / ("run" + std::to_string(id) + ".err");
        std::string cmd = "cd " + quote(work().string()) + " && " + prefix +
                          "env KESTREL_PLUGIN_PATH= " + env + " " + quote(KESTREL_CLI);
        for (const auto& a : args) cmd += " " + quote(a);
        cmd += " </dev/null >" + quote(out.string()) + " 2>" + quote(err.string());
        int status = std::system(cmd.c_str());
        CliResult r;
        r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        r.out = readText(out);
        r.err = readText(err);
        return r;
    }

    fs::path root_;
    std::atomic<int> runs_{0};
};

/// Generates a tiny canonical scene (noisy/frame_%04d.exr, frames 1..frames) under `dir` with
/// `kestrel scenegen`; false if this build has no scene generator.
inline bool makeScene(Sandbox& box, const fs::path& dir, int width, int height, int frames) {
    CliResult r =
        box.run({"scenegen", "--out", dir.string(), "--width", std::to_string(width), "--height",
                 std::to_string(height), "--frames", std::to_string(frames), "--spp", "2"});
    return r.code == 0;
}

/// Frame files matching `prefix`NNNN`suffix` in `dir` and stray temporary files (".*tmp*").
inline int countFiles(const fs::path& dir, const std::string& suffix) {
    int n = 0;
    std::error_code ec;
    if (!fs::exists(dir, ec)) return 0;
    for (const auto& e : fs::directory_iterator(dir)) {
        const std::string name = e.path().filename().string();
        if (name.size() >= suffix.size() &&
            name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0 && name[0] != '.')
            ++n;
    }
    return n;
}
inline int countTempFiles(const fs::path& dir) {
    int n = 0;
    std::error_code ec;
    if (!fs::exists(dir, ec)) return 0;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        const std::string name = e.path().filename().string();
        if (name[0] == '.' || name.find(".tmp") != std::string::npos) ++n;
    }
    return n;
}

inline std::string frameName(const std::string& prefix, int frame, const std::string& suffix) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "%04d", frame);
    return prefix + buf + suffix;
}

/// Source folder of the test graphs.
inline fs::path graphDir() {
    return fs::path(KESTREL_SOURCE_DIR) / "tests" / "cli" / "graphs";
}

/// FNV-1a of every regular file below `dir` (symlinks and FIFOs not followed), by path relative
/// to it: what a command must leave unchanged.
inline std::map<std::string, uint64_t> checksums(const fs::path& dir) {
    std::map<std::string, uint64_t> sums;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (!e.is_regular_file() || e.is_symlink()) continue;
        uint64_t h = 1469598103934665603ull;
        for (unsigned char c : readText(e.path())) h = (h ^ c) * 1099511628211ull;
        sums[fs::relative(e.path(), dir).string()] = h;
    }
    return sums;
}

/// Exactly one "error:" line, containing every needle, and no crash.
inline void expectOneError(const CliResult& r, std::initializer_list<std::string> needles) {
    auto lines = r.errorLines();
    ASSERT_EQ(lines.size(), 1u) << r.all();
    for (const auto& n : needles)
        EXPECT_NE(lines[0].find(n), std::string::npos) << "missing '" << n << "' in: " << lines[0];
    EXPECT_FALSE(looksLikeCrash(r.all())) << r.all();
}

}  // namespace clitest
