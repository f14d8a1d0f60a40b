// ExrLoader on canonical-layout files written here: values, matrices, pixel types, tiling,
// compression and data windows.
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <gtest/gtest.h>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {
Imath::Box2i box(int x0, int y0, int x1, int y1) {
    return Imath::Box2i({x0, y0}, {x1, y1});
}

/// A W x H canonical frame: value(channel k, x, y) = k * 1000 + y * W + x + 0.25.
Channels canonicalChannels(int W, int H) {
    Channels ch;
    const char* names[] = {"R",        "G",        "B",        "albedo.R", "albedo.G", "albedo.B",
                           "normal.X", "normal.Y", "normal.Z", "depth.Z",  "motion.X", "motion.Y"};
    int k = 0;
    for (const char* n : names) {
        auto& v = ch[n];
        v.resize(size_t(W) * size_t(H));
        for (int i = 0; i < W * H; ++i) v[size_t(i)] = float(k * 1000 + i) + 0.25f;
        ++k;
    }
    auto& id = ch["objectId.id"];
    id.resize(size_t(W) * size_t(H));
    for (int i = 0; i < W * H; ++i) id[size_t(i)] = i % 3 == 0 ? -1.f : float(i % 5);
    return ch;
}

Imf::Header canonicalAttributes() {
    Imf::Header h;
    h.insert("kestrel.layout", Imf::StringAttribute("canonical"));
    Imath::M44f w2p;
    w2p[0][3] = 7.f;  // x[row][col] == m[row][col]: translation in the last column
    h.insert("kestrel.worldToPixel", Imf::M44fAttribute(w2p));
    h.insert("kestrel.worldToCamera", Imf::M44fAttribute(Imath::M44f()));
    Imath::M44f o;
    o[1][3] = -2.f;
    h.insert("kestrel.objectToWorld.4", Imf::M44fAttribute(o));
    return h;
}
}  // namespace

TEST(ExrLoaderCanonical, ValuesIdsAndMatrices) {
    TempDir tmp("canon");
    const int W = 13, H = 7;
    Imf::Header attrs = canonicalAttributes();
    writeExr(tmp.path / "f.0001.exr", box(0, 0, W - 1, H - 1), canonicalChannels(W, H), {}, &attrs);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.facts["colorPixelType"], "float");  // a writer with pixelType auto keeps float
    EXPECT_EQ(rc.absent.count("color"), 0u);
    EXPECT_EQ(rc.absent.count("objectId"), 0u);
    ASSERT_EQ(rc.absent.count("emission"), 1u);
    EXPECT_NE(rc.absent["emission"].find("layout canonical has no channel emission.R/G/B"),
              std::string::npos)
        << rc.absent["emission"];
    h.useOutputs({"color", "albedo", "normal", "depth", "motion", "objectId"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("color").at(2, 4, 3), 2 * 1000 + 3 * W + 4 + 0.25f);
    EXPECT_EQ(h.out("albedo").at(0, 1, 1), 3 * 1000 + W + 1 + 0.25f);
    EXPECT_EQ(h.out("motion").at(1, 0, 0), 11 * 1000 + 0.25f);  // canonical motion: y down already
    EXPECT_EQ(h.out("objectId").atInt(0, 0), -1);
    EXPECT_EQ(h.out("objectId").atInt(1, 0), 1);
    EXPECT_EQ(h.out("objectId").atInt(4, 0), 4);
    ASSERT_TRUE(h.scene.hasCamera);
    EXPECT_EQ(h.scene.worldToPixel.m[0][3], 7.f);
    ASSERT_EQ(h.scene.objectToWorld.count(4), 1u);
    EXPECT_EQ(h.scene.objectToWorld[4].m[1][3], -2.f);
}

TEST(ExrLoaderCanonical, HalfTiledPiz) {
    TempDir tmp("half");
    const int W = 40, H = 21;  // not a multiple of the 16-pixel tiles
    Channels ch;
    for (const char* n : {"R", "G", "B"}) {
        auto& v = ch[n];
        for (int i = 0; i < W * H; ++i) v.push_back(float(i % 97) * 0.5f);  // exact in half
    }
    WriteOptions opt;
    opt.type = Imf::HALF;
    opt.tiled = true;
    opt.compression = Imf::PIZ_COMPRESSION;
    writeExr(tmp.path / "t.exr", box(0, 0, W - 1, H - 1), ch, opt);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "t.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.facts["colorPixelType"], "half");
    EXPECT_EQ(rc.facts.count(kestrel::kDepthPrecisionFact), 0u);  // no depth channel
    h.useOutputs({"color"});
    h.run();
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            ASSERT_EQ(h.out("color").at(1, x, y), float((y * W + x) % 97) * 0.5f);
}

TEST(ExrLoaderCanonical, EveryCompressionReads) {
    TempDir tmp("comp");
    Channels ch;
    for (const char* n : {"R", "G", "B"})
        for (int i = 0; i < 32 * 32; ++i) ch[n].push_back(float(i % 17));
    for (auto c :
         {Imf::NO_COMPRESSION, Imf::RLE_COMPRESSION, Imf::ZIPS_COMPRESSION, Imf::ZIP_COMPRESSION,
          Imf::PIZ_COMPRESSION, Imf::PXR24_COMPRESSION, Imf::B44_COMPRESSION, Imf::B44A_COMPRESSION,
          Imf::DWAA_COMPRESSION, Imf::DWAB_COMPRESSION}) {
        WriteOptions opt;
        opt.type = Imf::HALF;  // b44 compresses half only; values are exact small integers
        opt.compression = c;
        auto file = tmp.path / ("c" + std::to_string(int(c)) + ".exr");
        writeExr(file, box(0, 0, 31, 31), ch, opt);
        auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", file.string()}});
        h.useOutputs({"color"});
        h.run();
        // DWA is lossy: allow a small error there, exact elsewhere.
        float tol = (c == Imf::DWAA_COMPRESSION || c == Imf::DWAB_COMPRESSION) ? 0.5f : 0.f;
        EXPECT_NEAR(h.out("color").at(0, 5, 9), float((9 * 32 + 5) % 17), tol) << int(c);
    }
}

TEST(ExrLoaderCanonical, DataWindowInsideDisplayWindowFillsTheRest) {
    TempDir tmp("dwin");
    Channels ch;
    // data window (2,1)-(5,3) in a 0..9 x 0..5 display window
    for (const char* n : {"R", "G", "B", "depth.Z"})
        for (int i = 0; i < 4 * 3; ++i) ch[n].push_back(float(i + 1));
    WriteOptions opt;
    opt.display = box(0, 0, 9, 5);
    writeExr(tmp.path / "d.exr", box(2, 1, 5, 3), ch, opt);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "d.exr").string()}});
    h.useOutputs({"color", "depth"});
    h.run();
    ASSERT_EQ(h.out("color").width(), 10);
    ASSERT_EQ(h.out("color").height(), 6);
    EXPECT_EQ(h.out("color").at(0, 2, 1), 1.f);
    EXPECT_EQ(h.out("color").at(0, 5, 3), 12.f);
    EXPECT_EQ(h.out("color").at(0, 0, 0), 0.f);
    EXPECT_EQ(h.out("color").at(0, 6, 1), 0.f);
    EXPECT_EQ(h.out("depth").at(0, 9, 5), kestrel::kBackgroundDepth);  // no data: background
    EXPECT_EQ(h.out("depth").at(0, 3, 1), 2.f);
}

TEST(ExrLoaderCanonical, DataWindowBeyondDisplayWindowIsClipped) {
    TempDir tmp("dwout");
    Channels ch;
    // data window (-2,-1)-(4,2) over display (0,0)-(3,3): 7 x 4 values
    for (int i = 0; i < 7 * 4; ++i)
        ch["R"].push_back(float(i)), ch["G"].push_back(0), ch["B"].push_back(0);
    WriteOptions opt;
    opt.display = box(0, 0, 3, 3);
    writeExr(tmp.path / "o.exr", box(-2, -1, 4, 2), ch, opt);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "o.exr").string()}});
    h.useOutputs({"color"});
    h.run();
    ASSERT_EQ(h.out("color").width(), 4);
    // display (x, y) is data (x + 2, y + 1) in the 7-wide data rows
    EXPECT_EQ(h.out("color").at(0, 0, 0), float(1 * 7 + 2));
    EXPECT_EQ(h.out("color").at(0, 3, 2), float(3 * 7 + 5));
    EXPECT_EQ(h.out("color").at(0, 3, 3), 0.f);  // below the data window
}

TEST(ExrLoaderCanonical, DisplayWindowWithNonZeroOrigin) {
    TempDir tmp("origin");
    Channels ch;
    for (int i = 0; i < 3 * 2; ++i)
        ch["R"].push_back(float(i)), ch["G"].push_back(0), ch["B"].push_back(0);
    WriteOptions opt;
    opt.display = box(10, 20, 12, 21);
    writeExr(tmp.path / "n.exr", box(10, 20, 12, 21), ch, opt);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "n.exr").string()}});
    h.useOutputs({"color"});
    h.run();
    EXPECT_EQ(h.out("color").at(0, 2, 1), 5.f);
}

// Depth stored as half steps by up to 2^-10 of its value: the loader states it (the fact
// kDepthPrecisionFact), so filters that compare depths widen their tolerance; float depth
// states nothing.
TEST(ExrLoaderCanonical, HalfDepthIsStatedAsAFact) {
    TempDir tmp("half-depth");
    const int W = 8, H = 4;
    for (auto type : {Imf::HALF, Imf::FLOAT}) {
        Channels ch;
        for (const char* n : {"R", "G", "B", "depth.Z"}) ch[n].assign(size_t(W) * H, 2.f);
        WriteOptions opt;
        opt.type = type;
        writeExr(tmp.path / "d.exr", box(0, 0, W - 1, H - 1), ch, opt);
        auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "d.exr").string()}});
        RecordingResolve rc(1);
        h.pass().resolve(rc);
        if (type == Imf::HALF)
            EXPECT_EQ(rc.facts[kestrel::kDepthPrecisionFact], "0.0009765625");
        else
            EXPECT_EQ(rc.facts.count(kestrel::kDepthPrecisionFact), 0u);
    }
}
