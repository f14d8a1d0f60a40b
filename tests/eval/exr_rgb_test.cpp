// The comparison EXR reader: finds R, G, B whatever the layer prefix, and fails with one clear
// message naming the file. Real renderer files are read when ../shared is present.
#include <eval/ExrRgb.h>
#include <gtest/gtest.h>
#include <kestrel/Error.h>
#include <png.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ExrTestUtil.h"

namespace fs = std::filesystem;
using namespace kestrel;
using namespace kestrel::eval;
using testutil::tempDir;

namespace {

// Channel i holds (i + 1) + 0.01 x + 0.1 y.
void writeExr(const fs::path& path, int w, int h, const std::vector<std::string>& names,
              Imf::PixelType type = Imf::FLOAT) {
    testutil::writeExr(
        path, w, h, names, [](int i, int x, int y) { return float(i + 1) + 0.01f * x + 0.1f * y; },
        type);
}

// Expects `fn` to throw a kestrel::Error whose message contains every `parts`.
template <class Fn>
void expectErrorContaining(Fn fn, const std::vector<std::string>& parts) {
    try {
        fn();
        ADD_FAILURE() << "no error thrown";
    } catch (const kestrel::Error& e) {
        for (const auto& p : parts)
            EXPECT_NE(std::string(e.what()).find(p), std::string::npos)
                << "message '" << e.what() << "' lacks '" << p << "'";
    }
}

}  // namespace

TEST(ExrRgb, ChoosesLayer) {
    EXPECT_EQ(chooseRgbLayer({"B", "G", "R"}), "");
    EXPECT_EQ(chooseRgbLayer({"ViewLayer.DiffCol.R", "ViewLayer.DiffCol.G", "ViewLayer.DiffCol.B",
                              "ViewLayer.Combined.R", "ViewLayer.Combined.G",
                              "ViewLayer.Combined.B", "ViewLayer.Combined.A"}),
              "ViewLayer.Combined");
    EXPECT_EQ(chooseRgbLayer({"beauty.R", "beauty.G", "beauty.B", "Z"}), "beauty");
    EXPECT_EQ(chooseRgbLayer(
                  {"a.DiffCol.R", "a.DiffCol.G", "a.DiffCol.B", "a.Emit.R", "a.Emit.G", "a.Emit.B"},
                  "Emit"),
              "a.Emit");
    expectErrorContaining(
        [] {
            chooseRgbLayer({"x.R", "x.G", "x.B", "y.R", "y.G", "y.B"});
        },
        {"x", "y", "--layer"});
    expectErrorContaining([] { chooseRgbLayer({"R", "G", "Z"}); }, {"no R,G,B", "Z"});
    expectErrorContaining([] { chooseRgbLayer({"R", "G", "B"}, "Combined"); }, {"Combined"});
}

TEST(ExrRgb, ReadsPlainRgbStoredBgr) {
    const fs::path f = tempDir() / "plain.exr";
    writeExr(f, 5, 3, {"B", "G", "R"});  // stored B,G,R like GAMES202; values 1, 2, 3 (+ ramp)
    Image img = readExrRgb(f);
    ASSERT_EQ(img.width(), 5);
    ASSERT_EQ(img.height(), 3);
    EXPECT_FLOAT_EQ(img.at(0, 0, 0), 3.0f);  // R
    EXPECT_FLOAT_EQ(img.at(1, 0, 0), 2.0f);  // G
    EXPECT_FLOAT_EQ(img.at(2, 0, 0), 1.0f);  // B
    EXPECT_FLOAT_EQ(img.at(0, 4, 2), 3.0f + 0.04f + 0.2f);
}

TEST(ExrRgb, ReadsBlenderStyleCombinedAndHalf) {
    const fs::path d = tempDir();
    writeExr(d / "layered.exr", 4, 2,
             {"ViewLayer.DiffCol.R", "ViewLayer.DiffCol.G", "ViewLayer.DiffCol.B",
              "ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
              "ViewLayer.Combined.A"});
    Image img = readExrRgb(d / "layered.exr");
    EXPECT_FLOAT_EQ(img.at(0, 0, 0), 4.0f);  // Combined.R is the 4th channel written
    EXPECT_FLOAT_EQ(img.at(2, 1, 1), 6.0f + 0.01f + 0.1f);
    Image diff = readExrRgb(d / "layered.exr", "DiffCol");
    EXPECT_FLOAT_EQ(diff.at(0, 0, 0), 1.0f);

    writeExr(d / "half.exr", 3, 3, {"R", "G", "B"}, Imf::HALF);
    Image h = readExrRgb(d / "half.exr");
    EXPECT_NEAR(h.at(2, 2, 2), 3.0f + 0.02f + 0.2f, 2e-3);
}

TEST(ExrRgb, ErrorsNameTheFile) {
    const fs::path d = tempDir();
    expectErrorContaining([&] { readExrRgb(d / "missing.exr"); }, {"missing.exr", "No such file"});

    writeExr(d / "gray.exr", 2, 2, {"Y"});
    expectErrorContaining([&] { readExrRgb(d / "gray.exr"); }, {"gray.exr", "no R,G,B", "Y"});

    std::ofstream(d / "corrupt.exr") << "this is not an EXR file at all";
    expectErrorContaining([&] { readExrRgb(d / "corrupt.exr"); }, {"corrupt.exr"});

    // A truncated file: a valid header whose pixel data is cut off.
    writeExr(d / "full.exr", 64, 64, {"R", "G", "B"});
    std::ifstream in(d / "full.exr", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream(d / "truncated.exr", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    expectErrorContaining([&] { readExrRgb(d / "truncated.exr"); }, {"truncated.exr"});

    // Every error is a FrameError (a frame-level problem: --skip-bad-frames can skip it).
    EXPECT_THROW(readExrRgb(d / "gray.exr"), kestrel::FrameError);
}

TEST(ExrRgb, ReadsRealRendererFiles) {
    const fs::path shared = KESTREL_SHARED_DIR;
    const fs::path blenderRef = shared / "data/blender-sample-room/ref/frame_0001.exr";
    const fs::path blenderNoisy = shared / "data/blender-sample-room/noisy/frame_0001.exr";
    const fs::path games = shared / "data/games202-box/beauty_0.exr";
    if (!fs::exists(blenderRef) || !fs::exists(games))
        GTEST_SKIP() << "real data not found under " << shared;
    Image ref = readExrRgb(blenderRef);  // ViewLayer.Combined.R/G/B
    EXPECT_EQ(ref.width(), 320);
    EXPECT_EQ(ref.height(), 180);
    Image noisy = readExrRgb(blenderNoisy);  // 47 channels, several RGB layers: picks Combined
    EXPECT_EQ(noisy.extent(), ref.extent());
    Image beauty = readExrRgb(games);  // plain R, G, B
    EXPECT_EQ(beauty.width(), 512);
    EXPECT_EQ(beauty.height(), 512);
}

namespace {
/// A Radiance HDR (RGBE, uncompressed scan lines) of w x h pixels all equal to `rgb`.
void writeHdr(const fs::path& path, int w, int h, const float rgb[3]) {
    std::ofstream f(path, std::ios::binary);
    f << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " << h << " +X " << w << "\n";
    int e = 0;
    const float m = std::frexp(std::max({rgb[0], rgb[1], rgb[2]}), &e);
    const float scale = m * 256.f / std::max({rgb[0], rgb[1], rgb[2]});
    const unsigned char px[4] = {(unsigned char)(rgb[0] * scale), (unsigned char)(rgb[1] * scale),
                                 (unsigned char)(rgb[2] * scale), (unsigned char)(e + 128)};
    for (int i = 0; i < w * h; ++i) f.write(reinterpret_cast<const char*>(px), 4);
}

/// An 8-bit RGB PNG of w x h pixels all equal to `value`.
void writePng(const fs::path& path, int w, int h, unsigned char value) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = png_uint_32(w);
    image.height = png_uint_32(h);
    image.format = PNG_FORMAT_RGB;
    const std::vector<unsigned char> pixels(size_t(w) * size_t(h) * 3, value);
    ASSERT_TRUE(png_image_write_to_file(&image, path.c_str(), 0, pixels.data(), 0, nullptr));
}

/// Whether this build reads files other than EXR (OpenImageIO).
bool readsOtherImages(const fs::path& any) {
    try {
        readImageRgb(any);
        return true;
    } catch (const kestrel::Error& e) {
        return std::string(e.what()).find("no OpenImageIO") == std::string::npos;
    }
}
}  // namespace

TEST(ImageRgb, RadianceHdrReferenceIsReadLinear) {
    const fs::path dir = tempDir();
    const float rgb[3] = {1.f, 0.5f, 2.f};
    writeHdr(dir / "ref.0001.hdr", 4, 3, rgb);
    if (!readsOtherImages(dir / "ref.0001.hdr")) GTEST_SKIP() << "built without OpenImageIO";
    const Image img = readExrRgb(dir / "ref.0001.hdr");
    ASSERT_EQ(img.width(), 4);
    ASSERT_EQ(img.height(), 3);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.at(c, 3, 2), rgb[c], 0.01f * rgb[c]) << c;
}

TEST(ImageRgb, PngReferenceIsDecodedFromSrgb) {
    const fs::path dir = tempDir();
    writePng(dir / "ref.png", 5, 2, 188);
    if (!readsOtherImages(dir / "ref.png")) GTEST_SKIP() << "built without OpenImageIO";
    const Image img = readExrRgb(dir / "ref.png");
    ASSERT_EQ(img.width(), 5);
    // sRGB 188/255 is linear 0.5029.
    EXPECT_NEAR(img.at(1, 4, 1), std::pow((188.f / 255.f + 0.055f) / 1.055f, 2.4f), 1e-4f);
}

TEST(ImageRgb, UnreadableImageNamesTheFile) {
    const fs::path dir = tempDir();
    std::ofstream(dir / "ref.png") << "not a png";
    expectErrorContaining([&] { readExrRgb(dir / "ref.png"); }, {"ref.png"});
}
