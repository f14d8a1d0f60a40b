// Bench report writer on synthetic rows: the Pareto set of a hand-made case, the files, the
// inline SVG plots and the PNG crops.
#include <eval/BenchReport.h>
#include <gtest/gtest.h>
#include <png.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "ExrTestUtil.h"

namespace fs = std::filesystem;
using namespace kestrel;
using namespace kestrel::eval;

namespace {

BenchRow row(const std::string& name, double ms, double relMse, size_t frames = 3) {
    BenchRow r;
    r.name = name;
    r.msPerFrame = ms;
    for (size_t f = 0; f < frames; ++f) {
        FrameMetrics m;
        // Per-frame errors around relMse whose mean is exactly relMse.
        m.relMse = relMse * (f == 0 ? 0.5 : f == 1 ? 1.5 : 1.0);
        m.psnr = 30;
        m.ssim = 0.9;
        if (f) m.temporal = 0.01;
        r.errors.push_back(m);
    }
    r.passMs = {{"load", 0.2 * ms}, {"atrous", 0.7 * ms}, {"write", 0.1 * ms}};
    return r;
}

struct Spec {
    const char* name;
    double ms, relMse;
};
// BenchRow holds an Image (move-only), so rows are built in place.
std::vector<BenchRow> rows(std::initializer_list<Spec> specs) {
    std::vector<BenchRow> out;
    for (const Spec& s : specs) out.push_back(row(s.name, s.ms, s.relMse));
    return out;
}

std::string slurp(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}

Image gradient(int w, int h) {
    Image img(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) img.at(c, x, y) = 0.1f * float(x + y + c);
    return img;
}

}  // namespace

TEST(BenchReport, ParetoFrontOfHandMadeCase) {
    // (ms, relMSE): A (10, 0.1), B (20, 0.05), C (30, 0.08) dominated by B, D (5, 0.5),
    // E (20, 0.06) dominated by B (same time, more error), F (40, 0.05) dominated by B (same
    // error, slower), G (50, 0.01).
    std::vector<BenchRow> r = rows({{"A", 10, 0.1},
                                    {"B", 20, 0.05},
                                    {"C", 30, 0.08},
                                    {"D", 5, 0.5},
                                    {"E", 20, 0.06},
                                    {"F", 40, 0.05},
                                    {"G", 50, 0.01}});
    EXPECT_NEAR(r[0].mean().relMse, 0.1, 1e-12);
    EXPECT_EQ(paretoFront(r), (std::vector<size_t>{3, 0, 1, 6}));  // D, A, B, G by time
    // Two identical rows: neither dominates the other.
    EXPECT_EQ(paretoFront(rows({{"X", 1, 1}, {"Y", 1, 1}})), (std::vector<size_t>{0, 1}));
    EXPECT_TRUE(paretoFront({}).empty());
}

TEST(BenchReport, PngRoundTrip) {
    Image img = gradient(7, 5);
    std::vector<unsigned char> png = encodePng(img, ToneMap::Clamp);
    png_image info{};
    info.version = PNG_IMAGE_VERSION;
    ASSERT_TRUE(png_image_begin_read_from_memory(&info, png.data(), png.size()));
    EXPECT_EQ(info.width, 7u);
    EXPECT_EQ(info.height, 5u);
    info.format = PNG_FORMAT_RGB;
    std::vector<unsigned char> pixels(PNG_IMAGE_SIZE(info));
    ASSERT_TRUE(png_image_finish_read(&info, nullptr, pixels.data(), 0, nullptr));
    // Pixel (3, 2), green: clamp(0.1 * 6) = 0.6 -> 153.
    EXPECT_EQ(pixels[(2 * 7 + 3) * 3 + 1], 153);
}

TEST(BenchReport, WritesFilesWithPlotsAndCrops) {
    BenchReport r;
    r.title = "svgf <settings> & friends";
    r.frames = {5, 6, 7};
    r.rows = rows({{"svgf", 12, 0.02},
                   {"svgf alpha=0.05", 12.5, 0.03},
                   {"jbf", 30, 0.04},
                   {"noisy, \"raw\"", 0.5, 0.5}});
    r.rows[0].crop = gradient(16, 16);
    r.noisyCrop = gradient(16, 16);
    r.referenceCrop = gradient(16, 16);
    r.cropNote = "frame 6, x 0-15, y 0-15";
    const fs::path dir = testutil::tempDir() / "report";
    BenchFiles files = writeBenchReport(r, dir);
    for (const fs::path& p :
         {files.markdown, files.csv, files.framesCsv, files.passesCsv, files.html})
        EXPECT_TRUE(fs::exists(p)) << p;

    const std::string html = slurp(files.html);
    EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
    size_t svgs = 0;
    for (size_t p = html.find("<svg"); p != std::string::npos; p = html.find("<svg", p + 1)) ++svgs;
    EXPECT_EQ(svgs, 3u);  // error vs time, error per frame, per-pass time
    EXPECT_NE(html.find("Pareto front"), std::string::npos);
    size_t pngs = 0;
    for (size_t p = html.find("data:image/png;base64,"); p != std::string::npos;
         p = html.find("data:image/png;base64,", p + 1))
        ++pngs;
    EXPECT_EQ(pngs, 3u);  // noisy, the one output crop, reference
    EXPECT_NE(html.find("svgf &lt;settings&gt; &amp; friends"), std::string::npos);  // escaped
    EXPECT_EQ(html.find("<settings>"), std::string::npos);

    const std::string csv = slurp(files.csv);
    EXPECT_EQ(csv.rfind("setting,relMse,psnr,ssim,temporal,msPerFrame,pareto", 0), 0u);
    EXPECT_NE(csv.find("svgf,0.02,30,0.9,0.010000,12,1,0"), std::string::npos) << csv;
    EXPECT_NE(csv.find("svgf alpha=0.05,0.03,30,0.9,0.010000,12.5,0,0"), std::string::npos);
    EXPECT_NE(csv.find("\"noisy, \"\"raw\"\"\""), std::string::npos);  // RFC 4180 quoting
    const std::string frames = slurp(files.framesCsv);
    EXPECT_NE(frames.find("svgf,5,0.01,30,0.9,,0"), std::string::npos) << frames;
    EXPECT_NE(slurp(files.passesCsv).find("jbf,atrous,21"), std::string::npos);
    const std::string md = slurp(files.markdown);
    EXPECT_NE(md.find("| svgf | 0.02 | 30.00 | 0.9000 | 0.010000 | 0 | 12.00 | - | * |"),
              std::string::npos)
        << md;
}

namespace {

struct Label {
    double x0, y0, x1, y1;
    std::string text;
};
// The labels (class 'lbl') of the first SVG in `html`, boxes estimated as the writer does for
// 11 px sans-serif (the browser test, tests/cli/report_browser_test.sh, measures real ones).
std::vector<Label> firstPlotLabels(const std::string& html) {
    const std::string svg = html.substr(html.find("<svg"), html.find("</svg>") - html.find("<svg"));
    std::vector<Label> out;
    for (size_t p = svg.find("<text class='lbl'"); p != std::string::npos;
         p = svg.find("<text class='lbl'", p + 1)) {
        const double x = std::stod(svg.substr(svg.find("x='", p) + 3));
        const double y = std::stod(svg.substr(svg.find("y='", p) + 3));
        const size_t t0 = svg.find('>', p) + 1;
        const std::string text = svg.substr(t0, svg.find("</text>", t0) - t0);
        out.push_back({x, y - 10, x + 6.5 * double(text.size()), y + 3, text});
    }
    return out;
}

std::vector<double> circleYs(const std::string& html) {
    std::vector<double> ys;
    const std::string svg = html.substr(0, html.find("</svg>"));
    for (size_t p = svg.find("<circle"); p != std::string::npos; p = svg.find("<circle", p + 1))
        ys.push_back(std::stod(svg.substr(svg.find("cy='", p) + 4)));
    return ys;
}

}  // namespace

TEST(BenchReport, InputRowOffScaleAndLabelsApart) {
    // A sweep of close settings (3-4 ms, relMSE 0.010-0.018) and the unfiltered input, 50x worse:
    // the axis must spread the settings, not fit the input, and no two labels may overlap.
    BenchReport r;
    r.frames = {1, 2, 3};
    for (int k = 0; k < 8; ++k)
        r.rows.push_back(row("svgf sigmaL=" + std::to_string(k + 1), 3 + 0.1 * k,
                             0.010 + 0.001 * k));
    r.rows.push_back(row("svgf-fast", 3.05, 0.0105));
    for (int k = 0; k < 5; ++k)  // settings that change nothing measurable: one point
        r.rows.push_back(row("svgf tie " + std::to_string(k), 3.4 + 0.001 * k, 0.0140));
    r.rows.push_back(row("noisy input", 0, 0.8));
    r.rows.back().inputOnly = true;
    const std::string html = slurp(writeBenchReport(r, testutil::tempDir() / "offscale").html);

    const std::vector<double> ys = circleYs(html);
    ASSERT_EQ(ys.size(), 14u);  // the input is no circle on the axis
    const auto [lo, hi] = std::minmax_element(ys.begin(), ys.end());
    EXPECT_GT(*hi - *lo, 80.0) << "settings squeezed on a few pixels of the error axis";
    EXPECT_NE(html.find("noisy input: 30.0 dB, off scale"), std::string::npos);
    // The error-per-frame plot too: the input named off scale, no line of it.
    const std::string perFrame = html.substr(html.find("<h2>Error per frame</h2>"));
    EXPECT_NE(perFrame.find("noisy input: 30.0 dB, off scale"), std::string::npos);
    EXPECT_EQ(perFrame.find("<title>noisy input</title></polyline>"), std::string::npos);
    EXPECT_NE(perFrame.find("<title>svgf-fast</title></polyline>"), std::string::npos);

    const std::vector<Label> labels = firstPlotLabels(html);
    ASSERT_GE(labels.size(), 15u);
    for (size_t i = 0; i < labels.size(); ++i)
        for (size_t j = i + 1; j < labels.size(); ++j)
            EXPECT_FALSE(labels[i].x0 < labels[j].x1 && labels[j].x0 < labels[i].x1 &&
                         labels[i].y0 < labels[j].y1 && labels[j].y0 < labels[i].y1)
                << "'" << labels[i].text << "' overlaps '" << labels[j].text << "'";
}

TEST(BenchReport, PassChartGroupsChainsAndStages) {
    // svgf.json's passes with the split: two chains of the same stages, A-Trous iterations
    // numbered, then TAA: 21 passes, 10 stages.
    BenchReport r;
    r.frames = {1, 2, 3};
    r.rows.push_back(row("svgf", 10, 0.02));
    r.rows.back().passMs.clear();
    double total = 0;
    for (const std::string chain : {"diffuse", "specular"})
        for (const std::string stage : {"demodulate", "reprojection", "antilag", "temporal",
                                        "variance", "atrous0", "atrous1", "atrous2", "modulate"}) {
            r.rows.back().passMs.push_back({chain + "." + stage, 0.25});
            total += 0.25;
        }
    for (const std::string pass : {"background", "taaReprojection", "taa"})
        r.rows.back().passMs.push_back({pass, 0.5}), total += 0.5;
    r.rows.back().msPerFrame = total;
    const std::string html = slurp(writeBenchReport(r, testutil::tempDir() / "passes").html);
    const std::string chart = html.substr(html.find("<h2>Time per pass</h2>"));

    // The legend: one swatch per stage, no colour twice.
    std::vector<std::string> fills;
    for (size_t p = chart.find("width='10' height='10' fill='"); p != std::string::npos;
         p = chart.find("width='10' height='10' fill='", p + 1))
        fills.push_back(chart.substr(p + 29, chart.find('\'', p + 29) - p - 29));
    EXPECT_EQ(fills.size(), 10u);
    std::sort(fills.begin(), fills.end());
    EXPECT_EQ(std::unique(fills.begin(), fills.end()), fills.end()) << "a colour repeats";
    EXPECT_NE(chart.find("<title>diffuse \u00b7 atrous (3 passes): 0.750 ms</title>"),
              std::string::npos);
    // The bar's total is the table's ms per frame.
    EXPECT_NE(chart.find("<text class='total' x='"), std::string::npos);
    EXPECT_NE(chart.find(">" + std::to_string(total).substr(0, 4) + "</text>"), std::string::npos)
        << "total " << total;
}

TEST(BenchReport, TimingSpreadAndTiesWithinNoise) {
    // A and B: B more accurate, A faster by the median, but their ranges over the rounds
    // overlap: a tie on time, B the pick. C is slower than both beyond the noise.
    std::vector<BenchRow> r = rows({{"A", 1.0, 0.02}, {"B", 1.1, 0.01}, {"C", 3.0, 0.005}});
    r[0].msMin = 0.9, r[0].msMax = 1.2;
    r[1].msMin = 1.05, r[1].msMax = 1.3;
    r[2].msMin = 2.9, r[2].msMax = 3.1;
    const std::vector<size_t> front = paretoFront(r);
    ASSERT_EQ(front, (std::vector<size_t>{0, 1, 2}));
    EXPECT_EQ(timingTies(r, front), (std::vector<std::pair<size_t, size_t>>{{0, 1}}));
    // Without a spread nothing ties (one round says nothing about noise).
    std::vector<BenchRow> single = rows({{"A", 1.0, 0.02}, {"B", 1.1, 0.01}});
    EXPECT_TRUE(timingTies(single, paretoFront(single)).empty());

    BenchReport rep;
    rep.frames = {1, 2, 3};
    rep.rows = std::move(r);
    const BenchFiles files = writeBenchReport(rep, testutil::tempDir() / "ties");
    const std::string html = slurp(files.html), md = slurp(files.markdown);
    const std::string tie = "A (0.90-1.20 ms) and B (1.05-1.30 ms) tie on time within the spread "
                            "over the rounds: B, the lower error, is the pick";
    EXPECT_NE(html.find("<p class='tie'>Tie: " + tie), std::string::npos);
    EXPECT_NE(md.find("Tie: " + tie), std::string::npos) << md;
    EXPECT_EQ(md.find("Tie: B"), std::string::npos);  // B-C is no tie
    EXPECT_NE(html.find("<title>C: 2.90-3.10 ms over the rounds</title>"), std::string::npos);
    EXPECT_NE(md.find("| 1.00 | 0.90-1.20 | * |"), std::string::npos) << md;
    EXPECT_NE(slurp(files.csv).find(",0.9,1.2\n"), std::string::npos);
}

TEST(BenchReport, CropsWhereTheErrorIsWorst) {
    // A 96x64 frame, outputs equal to the reference but for a strong error at (70, 40) and a
    // weaker one at (10, 10): the worst window holds the first, the next the second, none
    // overlapping; a flat frame elsewhere would have been the old middle crop.
    const int w = 96, h = 64;
    Image ref = gradient(w, h), a = gradient(w, h), b = gradient(w, h);
    for (int c = 0; c < 3; ++c) {
        a.at(c, 70, 40) += 5, b.at(c, 71, 41) += 5;
        a.at(c, 10, 10) += 1;
    }
    const std::vector<CropRect> regions = worstRegions({a.view(), b.view()}, ref.view(), 16, 3);
    ASSERT_EQ(regions.size(), 3u);
    auto holds = [](const CropRect& r, int x, int y) {
        return x >= r.x0 && x < r.x0 + r.w && y >= r.y0 && y < r.y0 + r.h;
    };
    EXPECT_TRUE(holds(regions[0], 70, 40) && holds(regions[0], 71, 41));
    EXPECT_TRUE(holds(regions[1], 10, 10));
    for (size_t i = 0; i < regions.size(); ++i) {
        EXPECT_EQ(regions[i].w, 16);
        for (size_t j = i + 1; j < regions.size(); ++j)
            EXPECT_FALSE(regions[i].x0 < regions[j].x0 + 16 && regions[j].x0 < regions[i].x0 + 16 &&
                         regions[i].y0 < regions[j].y0 + 16 && regions[j].y0 < regions[i].y0 + 16);
    }

    BenchReport r;
    r.frames = {1, 2, 3};
    r.rows = rows({{"A", 2, 0.02}, {"B", 3, 0.01}, {"input", 0, 0.5}});
    r.rows[0].frame = gradient(w, h), r.rows[1].frame = gradient(w, h);
    r.rows[1].frame.at(0, 70, 40) += 5;
    r.rows[2].inputOnly = true;
    r.referenceFrame = gradient(w, h);
    r.noisyFrame = gradient(w, h);
    r.cropFrameNumber = 2;
    const std::string html = slurp(writeBenchReport(r, testutil::tempDir() / "crops").html);
    EXPECT_NE(html.find("<h3>Crop 1: x "), std::string::npos);
    EXPECT_NE(html.find("<h3>Crop 3: x "), std::string::npos);
    EXPECT_EQ(html.find("<h3>Crop 4: x "), std::string::npos);
    EXPECT_NE(html.find("alt='|B - reference| x"), std::string::npos) << "the difference image";
    EXPECT_NE(html.find("<img class='flip' alt='A/B: B | reference'"), std::string::npos);
    EXPECT_NE(html.find("data-other='data:image/png;base64,"), std::string::npos);
}
