// kestrel run with the inputs a new user gets wrong (docs/errors.md): each case checks the exit
// code, the one error line and what it names, and that no input frame or earlier output changed
// (content checksums of the whole sandbox before and after).
#include <sys/mount.h>
#include <sys/stat.h>

#include <map>
#include <thread>

#include "CliRunner.h"
#include "ExrCheck.h"

using namespace clitest;

namespace {

/// FNV-1a of every regular file below `dir` (symlinks not followed), by path relative to it.
std::map<std::string, uint64_t> checksums(const fs::path& dir) {
    std::map<std::string, uint64_t> sums;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (!e.is_regular_file() || e.is_symlink()) continue;
        uint64_t h = 1469598103934665603ull;
        for (unsigned char c : readText(e.path())) h = (h ^ c) * 1099511628211ull;
        sums[fs::relative(e.path(), dir).string()] = h;
    }
    return sums;
}

/// One "error:" line containing every needle.
void expectOneError(const CliResult& r, std::initializer_list<std::string> needles) {
    auto lines = r.errorLines();
    ASSERT_EQ(lines.size(), 1u) << r.all();
    for (const auto& n : needles)
        EXPECT_NE(lines[0].find(n), std::string::npos) << "missing '" << n << "' in: " << lines[0];
    EXPECT_FALSE(looksLikeCrash(r.all())) << r.all();
}

class CliBadInput : public ::testing::Test {
protected:
    void SetUp() override {
        // 32x24, 3 frames: about 0.05 s to generate.
        if (!makeScene(box, box.work() / "scene", 32, 24, 3))
            GTEST_SKIP() << "no scenegen in this build";
        before = checksums(box.work() / "scene");
    }
    CliResult run(std::vector<std::string> extra, const std::string& env = "") {
        std::vector<std::string> args = {"run",       (graphDir() / "copy.json").string(),
                                         "--input",   "scene/noisy/frame_####.exr",
                                         "--threads", "2"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args, env);
    }
    void expectInputsUntouched() {
        EXPECT_EQ(checksums(box.work() / "scene"), before) << "an input frame changed";
    }
    fs::path noisy() const { return box.work() / "scene" / "noisy"; }

    Sandbox box;
    std::map<std::string, uint64_t> before;
};

// --- outputs that are inputs -------------------------------------------------------------

TEST_F(CliBadInput, OutputPatternEqualToInputIsRefused) {
    auto r = run({"--frames", "1-3", "--output", "scene/noisy/frame_####.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"scene/noisy/frame_####.exr", "input.path", "output.path"});
    expectInputsUntouched();
}

TEST_F(CliBadInput, OutputThroughSymlinkedFolderIsRefused) {
    fs::create_directory_symlink("scene/noisy", box.work() / "alias");
    auto r = run({"--frames", "1-3", "--output", "alias/frame_####.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"alias/frame_0001.exr", "frame 1", "scene/noisy/frame_0001.exr"});
    expectInputsUntouched();
}

TEST_F(CliBadInput, OutputThroughDotDotIsRefused) {
    auto r = run({"--frames", "1-3", "--output", "scene/noisy/../noisy/frame_%04d.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"frame_0001.exr", "frame 1", "input.path"});
    expectInputsUntouched();
}

TEST_F(CliBadInput, OutputHardLinkedToInputIsRefused) {
    fs::create_directories(box.work() / "links");
    for (int f = 1; f <= 3; ++f)
        fs::create_hard_link(noisy() / frameName("frame_", f, ".exr"),
                             box.work() / "links" / frameName("l.", f, ".exr"));
    auto r = run({"--frames", "1-3", "--output", "links/l.####.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"links/l.0001.exr", "hard link"});
    expectInputsUntouched();
}

TEST_F(CliBadInput, OutputOntoReferenceIsRefused) {
    auto r = run({"--frames", "1-3", "--reference", "scene/ref/frame_####.exr", "--output",
                  "./scene/ref/frame_####.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"--reference", "scene/ref/frame_0001.exr"});
    expectInputsUntouched();
}

// --- an output every frame overwrites ----------------------------------------------------

TEST_F(CliBadInput, PlainOutputNameOverSeveralFramesIsRefused) {
    auto r = run({"--frames", "1-3", "--output", "out.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"'out.exr'", "3 frames", "out.####.exr"});
    EXPECT_FALSE(fs::exists(box.work() / "out.exr"));
    expectInputsUntouched();
}

TEST_F(CliBadInput, PlainOutputNameForOneFrameIsWritten) {
    auto r = run({"--frames", "2", "--output", "still.exr"});
    EXPECT_EQ(r.code, 0) << r.all();
    RgbImage img;
    EXPECT_TRUE(readRgb((box.work() / "still.exr").string(), img));
    expectInputsUntouched();
}

// --- graphs that are not graph files -----------------------------------------------------

TEST_F(CliBadInput, DeviceAsGraphIsRefusedAtOnce) {
    // Before the fix this read /dev/urandom until memory ran out; the limits turn that into
    // a failed test.
    auto r = box.runWithin(20, {"run", "/dev/urandom"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"/dev/urandom", "not a regular file"});
}

TEST_F(CliBadInput, DirectoryAsGraphSaysSo) {
    fs::create_directories(box.work() / "somedir");
    auto r = box.run({"run", "somedir/"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"somedir", "is a directory"});
}

TEST_F(CliBadInput, HugeGraphFileIsRefused) {
    writeText(box.work() / "big.json", std::string(17u << 20, ' '));
    auto r = box.run({"validate", "big.json"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"big.json", "16 MiB"});
}

// --- --set ------------------------------------------------------------------------------

TEST_F(CliBadInput, SetNumberBeyondDoubleNamesTheSet) {
    auto r = run({"--frames", "1", "--output", "out/c.####.exr", "--set", "tonemap.exposure=1e999"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"--set tonemap.exposure=1e999", "overflow"});
    EXPECT_EQ(r.err.find("json.exception"), std::string::npos) << r.all();
    EXPECT_FALSE(fs::exists(box.work() / "out"));
}

// --- --resume and damaged outputs --------------------------------------------------------

TEST_F(CliBadInput, ResumeRewritesTruncatedAndEmptyFrames) {
    const fs::path out = box.work() / "out";
    auto first = run({"--frames", "1-3", "--output", "out/c.####.exr"});
    ASSERT_EQ(first.code, 0) << first.all();
    // A crash left frame 2 empty (renamed before its data reached the disk) and frame 3 cut
    // short inside its last chunk (its offset table complete: only the chunk sizes tell).
    const auto size3 = fs::file_size(out / "c.0003.exr");
    fs::resize_file(out / "c.0002.exr", 0);
    fs::resize_file(out / "c.0003.exr", size3 - 10);
    const auto frame1 = checksums(out).at("c.0001.exr");

    auto r = run({"--frames", "1-3", "--output", "out/c.####.exr", "--resume"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.err.find("c.0002.exr is incomplete"), std::string::npos) << r.all();
    for (int f = 1; f <= 3; ++f) {
        RgbImage img;
        std::string why;
        EXPECT_TRUE(readRgb((out / frameName("c.", f, ".exr")).string(), img, &why))
            << "frame " << f << ": " << why;
    }
    EXPECT_EQ(checksums(out).at("c.0001.exr"), frame1) << "a complete frame was rewritten";
    EXPECT_EQ(countTempFiles(out), 0);
    expectInputsUntouched();
}

TEST_F(CliBadInput, ResumeRewritesAFrameCutInsideItsLastChunk) {
    const fs::path out = box.work() / "out";
    auto first = run({"--frames", "1-3", "--output", "out/c.####.exr"});
    ASSERT_EQ(first.code, 0) << first.all();
    fs::resize_file(out / "c.0003.exr", fs::file_size(out / "c.0003.exr") - 1);
    auto r = run({"--frames", "1-3", "--output", "out/c.####.exr", "--resume"});
    ASSERT_EQ(r.code, 0) << r.all();
    RgbImage img;
    std::string why;
    EXPECT_TRUE(readRgb((out / "c.0003.exr").string(), img, &why)) << why;
}

}  // namespace
