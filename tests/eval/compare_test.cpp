// Sequence comparison behind `kestrel compare`: frame discovery, temporal term, errors naming the
// file, table and JSON; and the 1-spp Blender sample against its reference (docs/design.md
// section 7).
#include <eval/Compare.h>
#include <gtest/gtest.h>
#include <kestrel/Error.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "ExrTestUtil.h"

namespace fs = std::filesystem;
using namespace kestrel;
using namespace kestrel::eval;
using testutil::tempDir;
using testutil::writeExr;

namespace {

// A sequence of w x h RGB frames: value = base + 0.05 * frame + small spatial ramp.
void writeSequence(const fs::path& dir, int first, int last, float base, int w = 16, int h = 12) {
    fs::create_directories(dir);
    for (int f = first; f <= last; ++f) {
        char name[64];
        std::snprintf(name, sizeof name, "frame_%04d.exr", f);
        writeExr(dir / name, w, h, {"R", "G", "B"}, [&](int c, int x, int y) {
            return base + 0.05f * f + 0.005f * x + 0.01f * y + 0.1f * c;
        });
    }
}

}  // namespace

TEST(Compare, IdenticalSequences) {
    const fs::path d = tempDir();
    writeSequence(d / "a", 1, 3, 0.2f);
    CompareOptions o;
    o.outPattern = (d / "a/frame_####.exr").string();
    o.refPattern = (d / "a/frame_%04d.exr").string();
    CompareResult r = compareSequences(o);
    ASSERT_EQ(r.frames.size(), 3u);
    EXPECT_EQ(r.frames[0].frame, 1);
    EXPECT_FALSE(r.frames[0].metrics.temporal.has_value());
    ASSERT_TRUE(r.frames[2].metrics.temporal.has_value());
    EXPECT_EQ(*r.frames[2].metrics.temporal, 0.0);
    EXPECT_EQ(r.mean.relMse, 0.0);
    EXPECT_DOUBLE_EQ(r.mean.psnr, 100.0);
    EXPECT_NEAR(r.mean.ssim, 1.0, 1e-6);
    ASSERT_TRUE(r.mean.temporal.has_value());
}

TEST(Compare, OffsetSequenceHandComputed) {
    // Output = reference + 0.1 everywhere, both brightening by 0.05 per frame.
    const fs::path d = tempDir();
    writeSequence(d / "out", 1, 4, 0.3f);
    writeSequence(d / "ref", 1, 4, 0.2f);
    CompareOptions o;
    o.outPattern = (d / "out/frame_####.exr").string();
    o.refPattern = (d / "ref/frame_####.exr").string();
    o.frames = {2, 4};
    o.toneMap = ToneMap::Clamp;
    CompareResult r = compareSequences(o);
    ASSERT_EQ(r.frames.size(), 2u);
    EXPECT_EQ(r.frames[1].frame, 4);
    // Clamp keeps values (all < 1), so the display MSE is 0.01: PSNR 20 dB.
    EXPECT_NEAR(r.frames[0].metrics.psnr, 20.0, 1e-3);
    // The output changes exactly like the reference between frames 2 and 4: temporal 0.
    EXPECT_NEAR(*r.frames[1].metrics.temporal, 0.0, 1e-6);
    EXPECT_GT(r.mean.relMse, 0.0);
    EXPECT_LT(r.mean.ssim, 1.0);

    const std::string table = formatTable(r);
    EXPECT_NE(table.find("relMSE"), std::string::npos);
    EXPECT_NE(table.find("mean"), std::string::npos);
    EXPECT_NE(table.find("20.00"), std::string::npos);
    EXPECT_EQ(table.find("NaN/Inf"), std::string::npos);  // no such column without bad pixels

    const nlohmann::json j = toJson(r);
    EXPECT_EQ(j["toneMap"], "clamp");
    ASSERT_EQ(j["frames"].size(), 2u);
    EXPECT_EQ(j["frames"][0]["frame"], 2);
    EXPECT_TRUE(j["frames"][0]["temporal"].is_null());
    EXPECT_NEAR(j["frames"][0]["psnr"].get<double>(), 20.0, 1e-3);
    EXPECT_EQ(j["mean"]["frames"], 2);
}

TEST(Compare, SingleFilesAndNonFinite) {
    const fs::path d = tempDir();
    writeExr(d / "out.exr", 4, 4, {"R", "G", "B"},
             [](int c, int x, int y) { return x == 1 && y == 2 && c == 0 ? NAN : 0.5f; });
    writeExr(d / "ref.exr", 4, 4, {"R", "G", "B"}, [](int, int, int) { return 0.5f; });
    CompareOptions o;
    o.outPattern = (d / "out.exr").string();
    o.refPattern = (d / "ref.exr").string();
    CompareResult r = compareSequences(o);
    ASSERT_EQ(r.frames.size(), 1u);
    EXPECT_FALSE(r.frames[0].frame.has_value());
    EXPECT_EQ(r.mean.nonFiniteOutput, 1u);
    EXPECT_TRUE(std::isfinite(r.mean.relMse));
    EXPECT_NE(formatTable(r).find("NaN/Inf"), std::string::npos);
}

TEST(Compare, ErrorsNameTheFile) {
    const fs::path d = tempDir();
    writeSequence(d / "out", 1, 3, 0.3f);
    writeSequence(d / "ref", 1, 2, 0.2f);
    CompareOptions o;
    o.outPattern = (d / "out/frame_####.exr").string();
    o.refPattern = (d / "ref/frame_####.exr").string();
    try {
        compareSequences(o);  // discovers 1..3 from the output; reference 3 is missing
        ADD_FAILURE() << "no error";
    } catch (const FrameError& e) {
        EXPECT_NE(std::string(e.what()).find("ref/frame_0003.exr"), std::string::npos) << e.what();
    }
    o.outPattern = (d / "none/frame_####.exr").string();
    EXPECT_THROW(compareSequences(o), Error);  // nothing matches

    writeSequence(d / "big", 1, 1, 0.2f, 20, 12);
    o.outPattern = (d / "big/frame_####.exr").string();
    try {
        compareSequences(o);
        ADD_FAILURE() << "no error";
    } catch (const FrameError& e) {
        EXPECT_NE(std::string(e.what()).find("20x12"), std::string::npos) << e.what();
    }
}

TEST(Compare, BlenderOneSppAgainstReference) {
    const fs::path room = fs::path(KESTREL_SHARED_DIR) / "data/blender-sample-room";
    if (!fs::exists(room / "ref/frame_0012.exr"))
        GTEST_SKIP() << "Blender sample not found under " << room;
    CompareOptions o;
    o.outPattern = (room / "noisy/frame_####.exr").string();
    o.refPattern = (room / "ref/frame_####.exr").string();
    o.frames = {5, 6, 7, 8, 9, 10, 11, 12};
    CompareResult r = compareSequences(o);
    // docs/design.md section 7, the 1-spp input: relMSE 0.505, PSNR 15.6, SSIM 0.111 (tone map:
    // Reinhard with gamma 2.2). Measured: 0.5048, 15.64 dB, 0.1107; temporal 0.1618.
    EXPECT_NEAR(r.mean.relMse, 0.505, 0.002);
    EXPECT_NEAR(r.mean.psnr, 15.6, 0.1);
    EXPECT_NEAR(r.mean.ssim, 0.111, 0.002);
    ASSERT_TRUE(r.mean.temporal.has_value());
    EXPECT_GT(*r.mean.temporal, 0.05);  // 1-spp noise is uncorrelated from frame to frame
}
