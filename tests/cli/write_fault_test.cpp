// The writer's failure paths, by fault injection (KESTREL_TEST_WRITE_FAULT=STEP:FRAME): the
// write of frame 2 fails at each step of the temp-file-then-rename sequence. Frames before it
// must stay intact, no temporary file may be left, and --resume must complete the sequence.
#include <map>

#include "CliRunner.h"
#include "ExrCheck.h"

using namespace clitest;

namespace {

class CliWriteFault : public ::testing::TestWithParam<const char*> {
protected:
    void SetUp() override {
        if (!makeScene(box, box.work() / "scene", 32, 24, 3))
            GTEST_SKIP() << "no scenegen in this build";
    }
    CliResult run(std::vector<std::string> extra, const std::string& env = "") {
        std::vector<std::string> args = {"run",      (graphDir() / "copy.json").string(),
                                         "--input",  "scene/noisy/frame_####.exr",
                                         "--frames", "1-3",
                                         "--output", "out/c.####.exr"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args, env);
    }
    Sandbox box;
};

}  // namespace

TEST_P(CliWriteFault, FailedFrameLeavesEarlierFramesAndResumeCompletes) {
    const std::string step = GetParam();
    const fs::path out = box.work() / "out";
    auto r = run({}, "KESTREL_TEST_WRITE_FAULT=" + step + ":2");
    EXPECT_EQ(r.code, 1) << r.all();
    auto lines = r.errorLines();
    ASSERT_EQ(lines.size(), 1u) << r.all();
    EXPECT_NE(lines[0].find("c.0002.exr"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("'" + step + "'"), std::string::npos) << lines[0];
    EXPECT_FALSE(looksLikeCrash(r.all())) << r.all();

    RgbImage img;
    std::string why;
    ASSERT_TRUE(readRgb((out / "c.0001.exr").string(), img, &why)) << why;
    const std::string frame1 = readText(out / "c.0001.exr");
    EXPECT_FALSE(fs::exists(out / "c.0002.exr"));
    EXPECT_FALSE(fs::exists(out / "c.0003.exr"));
    EXPECT_EQ(countTempFiles(out), 0) << "temporary file left after a failed " << step;

    auto resumed = run({"--resume"});
    ASSERT_EQ(resumed.code, 0) << resumed.all();
    for (int f = 1; f <= 3; ++f)
        EXPECT_TRUE(readRgb((out / frameName("c.", f, ".exr")).string(), img, &why))
            << "frame " << f << ": " << why;
    EXPECT_EQ(readText(out / "c.0001.exr"), frame1) << "--resume rewrote a complete frame";
    EXPECT_EQ(countTempFiles(out), 0);
}

INSTANTIATE_TEST_SUITE_P(EveryStep, CliWriteFault,
                         ::testing::Values("open", "chunk", "fsync", "rename"),
                         [](const auto& info) { return std::string(info.param); });
