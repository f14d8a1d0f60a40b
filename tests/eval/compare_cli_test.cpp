// `kestrel compare` end to end: exit codes 0 / 1 / 2, one-line errors, table and JSON on stdout.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "ExrTestUtil.h"

namespace fs = std::filesystem;
using kestrel::eval::testutil::tempDir;
using kestrel::eval::testutil::writeExr;

namespace {

struct CliRun {
    int code;
    std::string out, err;
};

std::string slurp(const fs::path& p) {
    std::FILE* f = std::fopen(p.c_str(), "rb");
    std::string s;
    if (!f) return s;
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) s.append(buf, n);
    std::fclose(f);
    return s;
}

CliRun runKestrel(const fs::path& dir, const std::string& args) {
    const std::string cmd = std::string("'") + KESTREL_CLI + "' " + args + " >'" +
                            (dir / "stdout").string() + "' 2>'" + (dir / "stderr").string() + "'";
    const int status = std::system(cmd.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "stdout"),
            slurp(dir / "stderr")};
}

}  // namespace

TEST(CompareCli, TableJsonAndExitCodes) {
    if (!fs::exists(KESTREL_CLI)) GTEST_SKIP() << "CLI not built: " << KESTREL_CLI;
    const fs::path d = tempDir();
    for (int f = 1; f <= 3; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "%04d.exr", f);
        writeExr(d / ("out_" + std::string(name)), 8, 8, {"R", "G", "B"},
                 [&](int c, int x, int y) { return 0.3f + 0.01f * (x + y + c + f); });
        writeExr(d / ("ref_" + std::string(name)), 8, 8, {"R", "G", "B"},
                 [&](int c, int x, int y) { return 0.25f + 0.01f * (x + y + c + f); });
    }
    const std::string out = "'" + (d / "out_####.exr").string() + "'";
    const std::string ref = "'" + (d / "ref_%04d.exr").string() + "'";

    CliRun table = runKestrel(d, "compare " + out + " " + ref);
    EXPECT_EQ(table.code, 0) << table.err;
    EXPECT_NE(table.out.find("mean"), std::string::npos) << table.out;
    EXPECT_NE(table.out.find("relMSE"), std::string::npos);

    CliRun json =
        runKestrel(d, "compare " + out + " " + ref + " --frames 2-3 --json --tonemap clamp");
    ASSERT_EQ(json.code, 0) << json.err;
    const nlohmann::json j = nlohmann::json::parse(json.out);
    ASSERT_EQ(j["frames"].size(), 2u);
    EXPECT_EQ(j["frames"][1]["frame"], 3);
    // Output = reference + 0.05 (clamp keeps values): PSNR = 10 log10(1 / 0.0025) = 26.02 dB.
    EXPECT_NEAR(j["mean"]["psnr"].get<double>(), 26.0206, 1e-3);
    EXPECT_NEAR(j["frames"][1]["temporal"].get<double>(), 0.0, 1e-6);

    CliRun missing = runKestrel(d, "compare " + out + " " + ref + " --frames 3-4");
    EXPECT_EQ(missing.code, 1);
    EXPECT_NE(missing.err.find("out_0004.exr"), std::string::npos) << missing.err;
    EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;

    EXPECT_EQ(runKestrel(d, "compare " + out + " " + ref + " --frames 3-x").code, 2);
    EXPECT_EQ(runKestrel(d, "compare " + out + " " + ref + " --tonemap aces").code, 2);
    EXPECT_EQ(runKestrel(d, "compare " + out).code, 2);
}
