// ExrLoader on missing, corrupt, truncated and hostile files, and on scenes lacking channels.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <fstream>

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

Channels rgb(int w, int h, float v = 1.f) {
    Channels ch;
    for (const char* n : {"R", "G", "B"}) ch[n].assign(size_t(w) * size_t(h), v);
    return ch;
}

/// Runs one frame and returns the FrameError's message ("" if none was thrown).
std::string frameError(const std::string& pattern, int64_t frame) {
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", pattern}});
    RecordingResolve rc(1);  // the layout is probed on frame 1, as the engine does
    h.pass().resolve(rc);
    h.useOutputs({"color"});
    h.ctx.frameNumber = frame;
    try {
        h.run();
    } catch (const kestrel::FrameError& e) {
        return e.what();
    }
    return "";
}

std::vector<char> bytesOf(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void writeBytes(const fs::path& p, const std::vector<char>& b) {
    std::ofstream(p, std::ios::binary).write(b.data(), std::streamsize(b.size()));
}
}  // namespace

TEST(ExrLoaderRobustness, MissingFrameIsAFrameErrorNamingTheFile) {
    TempDir tmp("missing");
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 3, 3), rgb(4, 4));
    std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
    EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
    EXPECT_NE(msg.find("frame 2"), std::string::npos) << msg;
}

TEST(ExrLoaderRobustness, MissingFirstFileAtResolveIsAnError) {
    TempDir tmp("nofirst");
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
    RecordingResolve rc(1);
    try {
        h.pass().resolve(rc);
        FAIL() << "no error";
    } catch (const kestrel::Error& e) {
        EXPECT_NE(std::string(e.what()).find("f.0001.exr"), std::string::npos) << e.what();
    }
}

TEST(ExrLoaderRobustness, GarbageFileIsAFrameError) {
    TempDir tmp("garbage");
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 3, 3), rgb(4, 4));
    std::ofstream(tmp.path / "f.0002.exr") << "this is not an EXR file at all";
    std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
    EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
    EXPECT_NE(msg.find("not an OpenEXR file"), std::string::npos) << msg;
}

TEST(ExrLoaderRobustness, TruncatedFileIsAFrameError) {
    TempDir tmp("trunc");
    // Noise compresses badly, so the cut falls inside pixel data rather than in the header.
    Channels ch = rgb(64, 64);
    uint32_t s = 1;
    for (auto& [n, v] : ch)
        for (auto& x : v) x = float((s = s * 1664525u + 1013904223u) >> 8);
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 63, 63), ch);
    writeExr(tmp.path / "f.0002.exr", box(0, 0, 63, 63), ch);
    auto b = bytesOf(tmp.path / "f.0002.exr");
    b.resize(b.size() / 2);
    writeBytes(tmp.path / "f.0002.exr", b);
    std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
    EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
    EXPECT_EQ(frameError((tmp.path / "f.####.exr").string(), 1), "");
}

TEST(ExrLoaderRobustness, HugeDataWindowIsRefusedBeforeAllocation) {
    TempDir tmp("huge");
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 0, 0), rgb(1, 1));
    writeExr(tmp.path / "f.0002.exr", box(0, 0, 0, 0), rgb(1, 1));
    // Patch the header's dataWindow (box2i: xmin ymin xmax ymax) to 100000 x 100000 pixels.
    auto b = bytesOf(tmp.path / "f.0002.exr");
    const std::string key("dataWindow\0box2i\0", 17);
    auto it = std::search(b.begin(), b.end(), key.begin(), key.end());
    ASSERT_NE(it, b.end());
    size_t at = size_t(it - b.begin()) + key.size() + 4;  // skip the attribute size
    int32_t window[4] = {0, 0, 99999, 99999};
    std::memcpy(&b[at], window, sizeof window);
    writeBytes(tmp.path / "f.0002.exr", b);
    // 1e10 pixels * 3 channels * 4 bytes would be 120 GB: the run must fail fast, not allocate.
    std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
    EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
    EXPECT_NE(msg.find("data window 100000x100000 exceeds maxPixels"), std::string::npos) << msg;
}

TEST(ExrLoaderRobustness, AbsentChannelNamesChannelAndLayout) {
    TempDir tmp("blendlike");
    Channels ch;
    for (const char* pass : {"Combined", "DiffCol", "DiffDir", "DiffInd", "GlossDir", "GlossInd"})
        for (const char* c : {"R", "G", "B"})
            ch[std::string("RenderLayer.") + pass + "." + c].assign(4, 0.5f);
    ch["RenderLayer.Vector.X"].assign(4, 0.f);
    ch["RenderLayer.Vector.Y"].assign(4, 0.f);
    writeExr(tmp.path / "b.0001.exr", box(0, 0, 1, 1), ch);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "b.####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    ASSERT_EQ(rc.absent.count("direct"), 1u);
    EXPECT_EQ(rc.absent["direct"], "layout blender has no channel RenderLayer.GlossCol.R/G/B");
    EXPECT_EQ(rc.absent["depth"], "layout blender has no channel RenderLayer.Depth.Z");
    EXPECT_EQ(rc.absent.count("diffuse"), 0u);
    EXPECT_EQ(rc.absent.count("motion"), 0u);
    EXPECT_EQ(rc.absent.count("emission"), 1u);
}

TEST(ExrLoaderRobustness, ChannelVanishingMidSequenceIsAFrameError) {
    TempDir tmp("vanish");
    Channels ch = rgb(2, 2);
    ch["depth.Z"].assign(4, 1.f);
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 1, 1), ch);
    writeExr(tmp.path / "f.0002.exr", box(0, 0, 1, 1), rgb(2, 2));
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
    h.useOutputs({"depth"});
    h.ctx.frameNumber = 1;
    h.run();
    try {
        h.run();
        FAIL() << "no error";
    } catch (const kestrel::FrameError& e) {
        EXPECT_NE(std::string(e.what()).find("no channel depth.Z"), std::string::npos) << e.what();
    }
}

TEST(ExrLoaderRobustness, BadChannelsParameterNamesTheItem) {
    TempDir tmp("badparam");
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 1, 1), rgb(2, 2));
    auto h = PassHarness::make<ExrLoader>(
        {1, 1}, {{"path", (tmp.path / "f.####.exr").string()}, {"channels", "albedo=Nope"}});
    RecordingResolve rc(1);
    try {
        h.pass().resolve(rc);
        FAIL() << "no error";
    } catch (const kestrel::Error& e) {
        EXPECT_NE(std::string(e.what()).find("'albedo=Nope'"), std::string::npos) << e.what();
    }
}
