// kestrel bench on a tiny generated scene: --crop-dump intermediates beside each setting's output
// in the crops where the error is worst, per-pass times that add up, --rounds.
#include <map>
#include <sstream>
#include <vector>

#include "CliRunner.h"

using namespace clitest;

namespace {

/// The report's crop figures: caption (alt text) -> the PNG's data URI.
std::map<std::string, std::string> figures(const std::string& html) {
    std::map<std::string, std::string> out;
    const std::string img = "<figure><img alt='", src = "src='data:image/png;base64,";
    for (size_t p = html.find(img); p != std::string::npos; p = html.find(img, p + 1)) {
        const size_t a = p + img.size();
        const std::string alt = html.substr(a, html.find('\'', a) - a);
        const size_t s = html.find(src, a) + src.size();
        out[alt] = html.substr(s, html.find('\'', s) - s);
    }
    return out;
}

/// The one caption starting with `prefix` and ending with `suffix` ("" when none or several).
std::string captionLike(const std::map<std::string, std::string>& f, const std::string& prefix,
                        const std::string& suffix) {
    std::string found;
    int n = 0;
    for (const auto& [alt, data] : f)
        if (alt.rfind(prefix, 0) == 0 && alt.size() >= suffix.size() &&
            alt.compare(alt.size() - suffix.size(), suffix.size(), suffix) == 0)
            found = alt, ++n;
    return n == 1 ? found : "";
}

}  // namespace

TEST(CliBench, CropDumpShowsIntermediatesBesideTheOutput) {
    Sandbox box;
    if (!makeScene(box, box.work() / "scene", 48, 32, 4))
        GTEST_SKIP() << "no scenegen in this build";
    auto bench = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = {
            "bench",       std::string(KESTREL_SOURCE_DIR) + "/graphs/svgf.json",
            "--input",     "scene/noisy/frame_####.exr",
            "--reference", "scene/ref/frame_####.exr",
            "--threads",   "2",
            "--report",    "rep"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    };
    const CliResult r = bench({"--crop-dump", "*atrous0.color", "--crop-dump", "*modulate.color"});
    ASSERT_EQ(r.code, 0) << r.all();
    const auto f = figures(readText(box.work() / "rep" / "bench.html"));
    ASSERT_TRUE(f.count("svgf")) << "the output crop";
    const std::string atrous = captionLike(f, "svgf: ", "atrous0.color");
    const std::string modulate = captionLike(f, "svgf: ", "modulate.color");
    ASSERT_FALSE(atrous.empty()) << r.all();
    ASSERT_FALSE(modulate.empty()) << r.all();
    // The room is point-sampled, so svgf.json leaves TAA out and its output is the modulated
    // colour: the same crop of the same frame gives the same PNG. A-Trous 0 is earlier: not it.
    EXPECT_TRUE(f.at(modulate) == f.at("svgf")) << modulate << " is not the output's crop";
    EXPECT_FALSE(f.at(atrous) == f.at("svgf")) << atrous << " is the output's crop";
    // The unfiltered-input row computes neither.
    EXPECT_TRUE(captionLike(f, "input (unfiltered): ", "").empty());
    // Crops where the error is worst: several (a 48x32 frame holds two 16x16 windows side by
    // side wherever the worst is), a difference image and an A/B flip of the best setting against
    // the reference.
    const std::string html = readText(box.work() / "rep" / "bench.html");
    EXPECT_NE(html.find("<h3>Crop 2: x "), std::string::npos);
    EXPECT_TRUE(f.count("noisy input") && f.count("reference"));
    EXPECT_NE(html.find("alt='|svgf - reference| x"), std::string::npos);
    EXPECT_NE(html.find("<img class='flip' alt='A/B: svgf | reference'"), std::string::npos);

    const CliResult typo = bench({"--crop-dump", "*atrous9.color"});
    EXPECT_EQ(typo.code, 2) << typo.all();
    ASSERT_EQ(typo.errorLines().size(), 1u) << typo.all();
    EXPECT_NE(typo.errorLines()[0].find("--crop-dump '*atrous9.color' matches no resource"),
              std::string::npos)
        << typo.all();
}

TEST(CliBench, PassTimesAddUpToTheTable) {
    // bench_passes.csv (and the per-pass chart) sum to bench.csv's ms per frame for every setting:
    // the passes' times are those of the setting's median frame.
    Sandbox box;
    if (!makeScene(box, box.work() / "scene", 32, 24, 6))
        GTEST_SKIP() << "no scenegen in this build";
    const CliResult r =
        box.run({"bench", std::string(KESTREL_SOURCE_DIR) + "/graphs/svgf.json", "--input",
                 "scene/noisy/frame_####.exr", "--reference", "scene/ref/frame_####.exr",
                 "--warmup", "1", "--threads", "1", "--report", "rep"});
    ASSERT_EQ(r.code, 0) << r.all();
    std::map<std::string, double> sums;
    std::istringstream passes(readText(box.work() / "rep" / "bench_passes.csv"));
    std::string line;
    std::getline(passes, line);  // header
    while (std::getline(passes, line))
        sums[line.substr(0, line.find(','))] += std::stod(line.substr(line.rfind(',') + 1));
    std::istringstream table(readText(box.work() / "rep" / "bench.csv"));
    std::getline(table, line);
    int checked = 0;
    while (std::getline(table, line)) {
        std::vector<std::string> f;
        std::istringstream fields(line);
        for (std::string v; std::getline(fields, v, ',');) f.push_back(v);
        ASSERT_GE(f.size(), 6u) << line;
        if (!sums.count(f[0])) continue;  // the input row has no computing pass
        const double ms = std::stod(f[5]);
        EXPECT_NEAR(sums[f[0]], ms, 1e-4 * ms + 1e-6) << f[0];
        ++checked;
    }
    EXPECT_EQ(checked, 1);
}

TEST(CliBench, RoundsGiveEachSettingItsSpread) {
    // --rounds 3: bench.csv gives each setting the lowest and highest of its rounds' medians,
    // around its ms per frame.
    Sandbox box;
    if (!makeScene(box, box.work() / "scene", 32, 24, 4))
        GTEST_SKIP() << "no scenegen in this build";
    const CliResult r =
        box.run({"bench", std::string(KESTREL_SOURCE_DIR) + "/graphs/svgf.json",
                 std::string(KESTREL_SOURCE_DIR) + "/graphs/svgf-fast.json", "--input",
                 "scene/noisy/frame_####.exr", "--reference", "scene/ref/frame_####.exr",
                 "--warmup", "1", "--threads", "1", "--rounds", "3", "--report", "rep"});
    ASSERT_EQ(r.code, 0) << r.all();
    std::istringstream table(readText(box.work() / "rep" / "bench.csv"));
    std::string line;
    std::getline(table, line);
    ASSERT_NE(line.find(",msMin,msMax"), std::string::npos) << line;
    int checked = 0;
    while (std::getline(table, line)) {
        std::vector<std::string> f;
        std::istringstream fields(line);
        for (std::string v; std::getline(fields, v, ',');) f.push_back(v);
        ASSERT_EQ(f.size(), 11u) << line;
        const double ms = std::stod(f[5]), lo = std::stod(f[9]), hi = std::stod(f[10]);
        if (ms == 0) continue;  // the input row: nothing timed
        EXPECT_GT(lo, 0) << line;
        EXPECT_LE(lo, ms * (1 + 1e-5)) << line;
        EXPECT_GE(hi * (1 + 1e-5), ms) << line;
        ++checked;
    }
    EXPECT_EQ(checked, 2);
    EXPECT_EQ(box.run({"bench", "--rounds", "0"}).code, 2) << "--rounds 0 accepted";
}

TEST(CliBench, EveryShippedGraphIsMeasuredOnAPointSampledScene) {
    // bench measures what a graph writes as colour: svgf-notaa (svgf.json less its TAA, its
    // colour edge rewired) lists the writer's optional alpha edge first, and was skipped on every
    // scene with "input.alpha cannot be produced" where the scene has no alpha.
    Sandbox box;
    if (!makeScene(box, box.work() / "scene", 48, 32, 3))
        GTEST_SKIP() << "no scenegen in this build";
    const std::string graphs = std::string(KESTREL_SOURCE_DIR) + "/graphs/";
    const CliResult r =
        box.run({"bench", graphs + "svgf.json", graphs + "svgf-notaa.json", "--input",
                 "scene/noisy/frame_####.exr", "--reference", "scene/ref/frame_####.exr",
                 "--threads", "2", "--rounds", "1", "--report", "rep"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_EQ(r.all().find("skipped"), std::string::npos) << r.all();
    // On a point-sampled render the two graphs compute the same (svgf.json's TAA is left out):
    // the same relMSE, PSNR, SSIM and temporal figures (bench.csv's columns 2-5).
    std::istringstream table(readText(box.work() / "rep" / "bench.csv"));
    std::map<std::string, std::string> errors;
    for (std::string line; std::getline(table, line);) {
        std::vector<std::string> cells;
        std::istringstream row(line);
        for (std::string c; std::getline(row, c, ',');) cells.push_back(c);
        if (cells.size() > 4) errors[cells[0]] = cells[1] + cells[2] + cells[3] + cells[4];
    }
    ASSERT_TRUE(errors.count("svgf") && errors.count("svgf-notaa"))
        << readText(box.work() / "rep" / "bench.csv");
    EXPECT_EQ(errors["svgf"], errors["svgf-notaa"]);
}
