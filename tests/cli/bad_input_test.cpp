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

TEST_F(CliBadInput, PreviewOntoTheFramesIsRefused) {
    auto r = run({"--frames", "1-3", "--output", "out/c.####.exr", "--set",
                  "output.preview=out/c.####.exr"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"out/c.0001.exr", "output.preview", "output.path"});
    EXPECT_FALSE(fs::exists(box.work() / "out"));
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
    auto r =
        run({"--frames", "1", "--output", "out/c.####.exr", "--set", "tonemap.exposure=1e999"});
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

// --- inputs that change or are still being written ---------------------------------------

TEST_F(CliBadInput, InputChangingSizeMidSequenceIsAFrameError) {
    // Frame 2 re-rendered at another size: no history of the others can filter it.
    ASSERT_TRUE(makeScene(box, box.root() / "other", 40, 30, 2));
    fs::copy_file(box.root() / "other" / "noisy" / "frame_0002.exr", noisy() / "frame_0002.exr",
                  fs::copy_options::overwrite_existing);
    before = checksums(box.work() / "scene");
    auto r = run({"--frames", "1-3", "--output", "out/c.####.exr"});
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"frame 2", "frame_0002.exr", "40x30", "frame_0001.exr", "32x24"});
    EXPECT_TRUE(fs::exists(box.work() / "out" / "c.0001.exr"));
    EXPECT_FALSE(fs::exists(box.work() / "out" / "c.0002.exr"));
    EXPECT_FALSE(looksLikeCrash(r.all())) << r.all();
    // With --skip-bad-frames it is skipped (history reset) and frame 3 has the sequence's size.
    auto skipped = run({"--frames", "1-3", "--output", "skip/c.####.exr", "--skip-bad-frames"});
    EXPECT_EQ(skipped.code, 0) << skipped.all();
    EXPECT_NE(skipped.err.find("skipped: frame 2"), std::string::npos) << skipped.all();
    EXPECT_EQ(skipped.err.find("resolution changed"), std::string::npos) << skipped.all();
    EXPECT_FALSE(fs::exists(box.work() / "skip" / "c.0002.exr"));
    RgbImage img;
    ASSERT_TRUE(readRgb((box.work() / "skip" / "c.0003.exr").string(), img));
    EXPECT_EQ(img.width, 32);
    expectInputsUntouched();
}

TEST_F(CliBadInput, InputChangingChannelSetMidSequenceIsAFrameError) {
    // A frame with colour only (what the copy graph writes) in a sequence with every AOV.
    auto rgb = run({"--frames", "2", "--output", "rgb/f.####.exr"});
    ASSERT_EQ(rgb.code, 0) << rgb.all();
    fs::copy_file(box.work() / "rgb" / "f.0002.exr", noisy() / "frame_0002.exr",
                  fs::copy_options::overwrite_existing);
    before = checksums(box.work() / "scene");
    const std::vector<std::string> args = {"run",      (graphDir() / "taa.json").string(),
                                           "--input",  "scene/noisy/frame_####.exr",
                                           "--frames", "1-3"};
    auto withOutput = [&](const char* out, bool skip) {
        auto a = args;
        a.insert(a.end(), {"--output", out});
        if (skip) a.push_back("--skip-bad-frames");
        return box.run(a);
    };
    auto r = withOutput("out/t.####.exr", false);
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"frame 2", "frame_0002.exr", "no channel"});
    EXPECT_TRUE(fs::exists(box.work() / "out" / "t.0001.exr"));
    // With --skip-bad-frames the frame is skipped with a warning and the run goes on.
    auto skipped = withOutput("skip/t.####.exr", true);
    EXPECT_EQ(skipped.code, 0) << skipped.all();
    EXPECT_NE(skipped.err.find("skipped: frame 2"), std::string::npos) << skipped.all();
    EXPECT_TRUE(fs::exists(box.work() / "skip" / "t.0003.exr"));
    expectInputsUntouched();
}

TEST_F(CliBadInput, HalfWrittenInputIsAFrameError) {
    // A renderer still writing frame 2: the file holds its header and part of its chunks.
    fs::resize_file(noisy() / "frame_0002.exr", fs::file_size(noisy() / "frame_0002.exr") / 2);
    before = checksums(box.work() / "scene");
    auto r = run({"--frames", "1-3", "--output", "out/c.####.exr"});
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"frame_0002.exr", "frame 2"});
    RgbImage img;
    EXPECT_TRUE(readRgb((box.work() / "out" / "c.0001.exr").string(), img));
    EXPECT_FALSE(fs::exists(box.work() / "out" / "c.0002.exr"));
    EXPECT_EQ(countTempFiles(box.work() / "out"), 0);
    expectInputsUntouched();
}

TEST_F(CliBadInput, JustCreatedEmptyInputIsAFrameError) {
    fs::resize_file(noisy() / "frame_0003.exr", 0);
    before = checksums(box.work() / "scene");
    auto r = run({"--frames", "1-3", "--output", "out/c.####.exr"});
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"frame_0003.exr", "frame 3"});
    expectInputsUntouched();
}

// --- output folders that refuse writes ---------------------------------------------------

/// Mounts a tmpfs at `dir` (root only); false when this machine does not allow it.
bool mountTmpfs(const fs::path& dir, const char* options) {
    fs::create_directories(dir);
    return ::mount("tmpfs", dir.c_str(), "tmpfs", 0, options) == 0;
}

TEST_F(CliBadInput, ReadOnlyOutputFolderFailsBeforeFrameOne) {
    const fs::path ro = box.work() / "ro";
    bool mounted = false;
    if (::geteuid() == 0) {
        // Root writes through permission bits: only a read-only mount refuses it.
        mounted = mountTmpfs(ro, "size=64k");
        if (!mounted) GTEST_SKIP() << "root without mount(2): cannot make a read-only folder";
        if (::mount(nullptr, ro.c_str(), nullptr, MS_REMOUNT | MS_RDONLY, nullptr) != 0) {
            ::umount(ro.c_str());
            GTEST_SKIP() << "cannot remount the tmpfs read-only";
        }
    } else {
        fs::create_directories(ro);
        fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
    }
    auto r = run({"--frames", "1-3", "--output", "ro/c.####.exr"});
    if (mounted)
        ::umount(ro.c_str());
    else
        fs::permissions(ro, fs::perms::owner_all);
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"ro", "not writable"});
    EXPECT_EQ(r.err.find("frame 1:"), std::string::npos) << r.all();
    expectInputsUntouched();
}

TEST_F(CliBadInput, FullDiskFailsNamingTheFrameAndKeepsEarlierOutputs) {
    const fs::path disk = box.work() / "disk";
    if (::geteuid() != 0 || !mountTmpfs(disk, "size=64k"))
        GTEST_SKIP() << "needs root and mount(2) for a small tmpfs";
    // An earlier run's frame, then filler up to the last byte.
    auto earlier = run({"--frames", "1", "--output", "disk/c.####.exr"});
    bool filled = earlier.code == 0;
    {
        std::ofstream fill(disk / "filler", std::ios::binary);
        std::string block(4096, 'x');
        while (fill.write(block.data(), std::streamsize(block.size())) && fill.flush()) {
        }
    }
    const auto kept = checksums(disk);
    auto r = run({"--frames", "1-3", "--output", "disk/c.####.exr"});
    const auto after = checksums(disk);
    const int temps = countTempFiles(disk);
    ::umount(disk.c_str());
    ASSERT_TRUE(filled) << earlier.all();
    EXPECT_EQ(r.code, 1) << r.all();
    expectOneError(r, {"disk"});
    EXPECT_EQ(after, kept) << "an earlier output changed on a full disk";
    EXPECT_EQ(temps, 0) << "temporary files left on the full disk";
    expectInputsUntouched();
}

// --- two runs, one output ----------------------------------------------------------------

TEST_F(CliBadInput, TwoRunsWritingTheSameOutputsAtOnce) {
    CliResult a, b;
    std::thread other([&] { b = run({"--frames", "1-3", "--output", "out/c.####.exr"}); });
    a = run({"--frames", "1-3", "--output", "out/c.####.exr"});
    other.join();
    EXPECT_EQ(a.code, 0) << a.all();
    EXPECT_EQ(b.code, 0) << b.all();
    for (int f = 1; f <= 3; ++f) {
        RgbImage img;
        std::string why;
        EXPECT_TRUE(readRgb((box.work() / "out" / frameName("c.", f, ".exr")).string(), img, &why))
            << "frame " << f << ": " << why;
    }
    EXPECT_EQ(countTempFiles(box.work() / "out"), 0);
    expectInputsUntouched();
}

// --- plugins ----------------------------------------------------------------------------

TEST_F(CliBadInput, PluginFolderWithAFileThatIsNotAPlugin) {
    writeText(box.work() / "plugins" / "README.txt", "notes, not a plugin\n");
    auto ok = run({"--frames", "1", "--output", "out/c.####.exr"}, "KESTREL_PLUGIN_PATH=plugins");
    EXPECT_EQ(ok.code, 0) << "a non-module file must be ignored\n" << ok.all();

    writeText(box.work() / "plugins" / "broken.so", "not a shared library\n");
    auto r = run({"--frames", "1", "--output", "out2/c.####.exr"}, "KESTREL_PLUGIN_PATH=plugins");
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"plugins/broken.so", "cannot be loaded"});
    EXPECT_FALSE(fs::exists(box.work() / "out2"));
}

TEST_F(CliBadInput, PluginPathToNothingIsAWarning) {
    auto r = run({"--frames", "1", "--output", "out/c.####.exr"},
                 "KESTREL_PLUGIN_PATH=/nonexistent/kestrel-plugins");
    EXPECT_EQ(r.code, 0) << r.all();
    EXPECT_NE(
        r.err.find("warning: KESTREL_PLUGIN_PATH: /nonexistent/kestrel-plugins does not exist"),
        std::string::npos)
        << r.all();
}

}  // namespace
