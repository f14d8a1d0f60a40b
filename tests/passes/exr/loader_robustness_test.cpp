// ExrLoader on missing, corrupt, truncated and hostile files, and on scenes lacking channels.
#include <OpenEXR/ImfBoxAttribute.h>
#include <OpenEXR/ImfChromaticitiesAttribute.h>
#include <OpenEXR/ImfDeepImageStateAttribute.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfEnvmapAttribute.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFloatVectorAttribute.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfKeyCodeAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOpaqueAttribute.h>
#include <OpenEXR/ImfPreviewImageAttribute.h>
#include <OpenEXR/ImfRationalAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfStringVectorAttribute.h>
#include <OpenEXR/ImfTimeCodeAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "ExrInput.h"
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

/// Where the value of attribute `name` of type `type` starts (after its 4-byte size).
size_t valueAt(const std::vector<char>& b, const std::string& name, const std::string& type) {
    const std::string key = name + '\0' + type + '\0';
    auto it = std::search(b.begin(), b.end(), key.begin(), key.end());
    EXPECT_NE(it, b.end()) << name;
    return size_t(it - b.begin()) + key.size() + 4;
}

/// Peak resident memory of this process so far, in MB.
long peakRssMb() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_maxrss / 1024;
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

// Regression (exr_fuzzer finding oom-685d828a, fuzz/FINDINGS.md): Imf::Header::readFrom allocates
// each attribute at its declared size before reading it, so a few hundred bytes declaring a 2 GB
// string made OpenEXR allocate and zero 2 GB (libFuzzer: out-of-memory past 2048 MB). Every
// declared size is now checked against the bytes left in the file first.
TEST(ExrLoaderRobustness, AttributeLargerThanTheFileIsRefusedBeforeAllocation) {
    for (const std::string type : {"string", "someUnknownType"}) {
        SCOPED_TRACE(type);
        TempDir tmp("hugeattr");
        writeExr(tmp.path / "f.0001.exr", box(0, 0, 1, 1), rgb(2, 2));
        writeExr(tmp.path / "f.0002.exr", box(0, 0, 1, 1), rgb(2, 2));
        // A first attribute (right after magic and version) declaring a 1 GB value.
        auto b = bytesOf(tmp.path / "f.0002.exr");
        std::string attr = "x" + std::string(1, '\0') + type + std::string(1, '\0');
        const int32_t size = int32_t(1) << 30;
        attr.append(reinterpret_cast<const char*>(&size), 4);
        b.insert(b.begin() + 8, attr.begin(), attr.end());
        writeBytes(tmp.path / "f.0002.exr", b);
        const long before = peakRssMb();
        std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
        EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
        EXPECT_NE(msg.find("attribute 'x' (" + type + ") declares a 1073741824-byte value"),
                  std::string::npos)
            << msg;
        EXPECT_NE(msg.find("refused before allocating"), std::string::npos) << msg;
        EXPECT_LT(peakRssMb() - before, 200);  // a string would have zeroed 1024 MB
    }
}

// A declared size that differs from what OpenEXR reads for the type (a box2i is 16 bytes, a
// channel list ends at its empty name) would make the size check and OpenEXR's parse disagree
// about where the next attribute starts: refused as corrupt.
TEST(ExrLoaderRobustness, AttributeSizeDisagreeingWithItsTypeIsRefused) {
    TempDir tmp("attrsize");
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 1, 1), rgb(2, 2));
    const auto good = bytesOf(tmp.path / "f.0001.exr");
    for (const auto& [name, type, expect] :
         {std::tuple<std::string, std::string, std::string>{"dataWindow", "box2i", "its type's 16"},
          {"channels", "chlist", "the channel list"}}) {
        auto b = good;
        const int32_t zero = 0;
        std::memcpy(&b[valueAt(b, name, type) - 4], &zero, 4);
        writeBytes(tmp.path / "f.0002.exr", b);
        std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
        EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
        EXPECT_NE(msg.find("attribute '" + name + "' (" + type + "): " + expect +
                           " does not match its declared size 0"),
                  std::string::npos)
            << msg;
    }
}

// OpenEXR allocates the chunk offset table (8 bytes per scan-line block or tile) when it opens a
// file: a 1 x 100000000 window fits maxPixels but declares 6.25 million ZIP blocks in a file of a
// few hundred bytes.
TEST(ExrLoaderRobustness, ChunkTableLargerThanTheFileIsRefusedBeforeAllocation) {
    TempDir tmp("chunks");
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 0, 0), rgb(1, 1));
    writeExr(tmp.path / "f.0002.exr", box(0, 0, 0, 0), rgb(1, 1));
    auto b = bytesOf(tmp.path / "f.0002.exr");
    int32_t window[4] = {0, 0, 0, 99999999};
    std::memcpy(&b[valueAt(b, "dataWindow", "box2i")], window, sizeof window);
    writeBytes(tmp.path / "f.0002.exr", b);
    std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
    EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
    EXPECT_NE(msg.find("header declares 6250000 chunks (data window 1x100000000), whose offset "
                       "table alone needs 50000000 bytes"),
              std::string::npos)
        << msg;
}

// Tile buffers are sized by the tile description, not the image, and Imf::InputFile caches a
// row of tiles (window width x tile height) to serve scan lines: a 6 x 5 image with 50331652 x 4
// tiles made OpenEXR allocate 1.2 GB, a 32000 x 1 one with 16 x 4096 tiles 524 MB a channel
// (exr_fuzzer, after the attribute fix).
TEST(ExrLoaderRobustness, OversizedTileIsRefusedBeforeAllocation) {
    struct Case {
        Imath::Box2i window;
        uint32_t tile[2];
        std::string expect;
    };
    const Case cases[] = {
        {box(0, 0, 5, 4),
         {50331652, 4},
         "chunk buffer (tile 50331652x4, 12 bytes per pixel) needs 2415919296 bytes, more than "
         "16 bytes x maxPixels 134217728 = 2147483648 (refused before allocating)"},
        {box(0, 0, 31999, 0),
         {16, 65536},
         "chunk buffer (tile 16x65536 in rows of 32000x65536, 12 bytes per pixel) needs "
         "25165824000 bytes"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.expect);
        TempDir tmp("hugetile");
        WriteOptions tiled;
        tiled.tiled = true;
        const int w = c.window.max.x + 1, h = c.window.max.y + 1;
        writeExr(tmp.path / "f.0001.exr", c.window, rgb(w, h), tiled);
        writeExr(tmp.path / "f.0002.exr", c.window, rgb(w, h), tiled);
        auto b = bytesOf(tmp.path / "f.0002.exr");
        std::memcpy(&b[valueAt(b, "tiles", "tiledesc")], c.tile, sizeof c.tile);
        writeBytes(tmp.path / "f.0002.exr", b);
        EXPECT_EQ(frameError((tmp.path / "f.####.exr").string(), 1), "");
        std::string msg = frameError((tmp.path / "f.####.exr").string(), 2);
        EXPECT_NE(msg.find("f.0002.exr"), std::string::npos) << msg;
        EXPECT_NE(msg.find(c.expect), std::string::npos) << msg;
    }
}

// The size checks must not refuse a valid header: one attribute of every type OpenEXR 3.1
// reads, plus an unknown (opaque) one.
TEST(ExrLoaderRobustness, HeaderWithEveryAttributeTypeLoads) {
    TempDir tmp("alltypes");
    Imf::Header extra;
    auto add = [&](const std::string& n, const Imf::Attribute& a) {
        extra.insert("kestrel.t." + n, a);
    };
    add("box2i", Imf::Box2iAttribute(box(1, 2, 3, 4)));
    add("box2f", Imf::Box2fAttribute(Imath::Box2f({0, 0}, {1, 1})));
    add("chromaticities", Imf::ChromaticitiesAttribute(Imf::Chromaticities()));
    add("deepImageState", Imf::DeepImageStateAttribute(Imf::DIS_MESSY));
    add("double", Imf::DoubleAttribute(2.5));
    add("envmap", Imf::EnvmapAttribute(Imf::ENVMAP_CUBE));
    add("float", Imf::FloatAttribute(1.5f));
    add("floatvector", Imf::FloatVectorAttribute({1.f, 2.f, 3.f}));
    add("int", Imf::IntAttribute(7));
    add("keycode", Imf::KeyCodeAttribute(Imf::KeyCode()));
    add("m33f", Imf::M33fAttribute(Imath::M33f()));
    add("m33d", Imf::M33dAttribute(Imath::M33d()));
    add("m44f", Imf::M44fAttribute(Imath::M44f()));
    add("m44d", Imf::M44dAttribute(Imath::M44d()));
    Imf::PreviewRgba px[6];
    add("preview", Imf::PreviewImageAttribute(Imf::PreviewImage(3, 2, px)));
    add("rational", Imf::RationalAttribute(Imf::Rational(24000, 1001)));
    add("string", Imf::StringAttribute("canonical-ish"));
    add("emptystring", Imf::StringAttribute(""));
    add("stringvector", Imf::StringVectorAttribute({"a", "", "bcd"}));
    add("timecode", Imf::TimeCodeAttribute(Imf::TimeCode(1, 2, 3, 4)));
    add("v2i", Imf::V2iAttribute({1, 2}));
    add("v2f", Imf::V2fAttribute({1, 2}));
    add("v2d", Imf::V2dAttribute({1, 2}));
    add("v3i", Imf::V3iAttribute({1, 2, 3}));
    add("v3f", Imf::V3fAttribute({1, 2, 3}));
    add("v3d", Imf::V3dAttribute({1, 2, 3}));
    add("opaque", Imf::OpaqueAttribute("someUnknownType"));
    writeExr(tmp.path / "f.0001.exr", box(0, 0, 1, 1), rgb(2, 2, 0.25f), {}, &extra);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
    h.useOutputs({"color"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("color").at(0, 1, 1), 0.25f);
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
    // Named as Blender's UI names it, with the denoiser feature that would stand in for it.
    EXPECT_EQ(rc.absent["depth"],
              "layout blender has no channel RenderLayer.Depth.Z (nor RenderLayer.Denoising "
              "Depth): enable View Layer > Passes > Data > Z");
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

namespace {
/// Opens the FIFO at `path` for writing after `seconds` and closes it, so that a reader blocked
/// on it (the defect under test) ends with EOF and fails the test instead of hanging it.
std::thread unblockLater(const fs::path& path, int seconds) {
    return std::thread([path, seconds] {
        for (int i = 0; i < seconds * 10; ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
            if (!fs::exists(path)) return;  // removed: the reader never opened it
        }
        const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK);
        if (fd >= 0) ::close(fd);
    });
}

/// The message of the Error `fn` throws ("" if none).
template <class Fn>
std::string errorOf(Fn fn) {
    try {
        fn();
    } catch (const kestrel::Error& e) {
        return e.what();
    }
    return "";
}
}  // namespace

// Issue 40 item 9: a FIFO where camera.json or a GAMES202 .mat is expected blocked the read
// forever; every reader refuses what is not a regular file (kestrel/InputFiles.h).
TEST(ExrLoaderRobustness, FifoSidecarsAreRefusedWithoutReading) {
    TempDir dir("exr-fifo-sidecars");
    for (const char* name : {"camera.json", "matrix_1.mat"}) {
        const fs::path fifo = dir.path / name;
        ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
        std::thread guard = unblockLater(fifo, 5);
        const std::string msg = errorOf([&] {
            if (std::string(name) == "camera.json") {
                kestrel::exr::BlenderCameras cameras(fifo);
            } else {
                kestrel::SceneData scene;
                kestrel::exr::readGames202Matrices(fifo, scene);
            }
        });
        fs::remove(fifo);
        guard.join();
        EXPECT_NE(msg.find(fifo.string()), std::string::npos) << msg;
        EXPECT_NE(msg.find("not a regular file"), std::string::npos) << msg;
    }
}

// Issue 40 item 10: a data window the file cannot hold (OpenImageIO refuses one declaring over
// 10,000 times the file's bytes and over 1 GiB) was allocated in full before the pixels were
// found missing. 20000x6000 float RGB declares 1.44 GB in a file of about 50 KB.
TEST(ExrLoaderRobustness, DataWindowAbsurdForTheFileSizeIsRefusedBeforeAllocation) {
    TempDir tmp("declared");
    Channels ch = rgb(64, 64);
    uint32_t s = 1;  // noise: the file keeps its ~49 KB, room for the forged offset table
    for (auto& [n, v] : ch)
        for (auto& x : v) x = float((s = s * 1664525u + 1013904223u) >> 8);
    for (const char* f : {"f.0001.exr", "f.0002.exr"})
        writeExr(tmp.path / f, box(0, 0, 63, 63), ch);
    const fs::path forged = tmp.path / "f.0002.exr";
    auto b = bytesOf(forged);
    int32_t window[4] = {0, 0, 19999, 5999};
    std::memcpy(&b[valueAt(b, "dataWindow", "box2i")], window, sizeof window);
    writeBytes(forged, b);
    const std::string msg =
        errorOf([&] { kestrel::exr::ExrInput in(forged.string(), int64_t(1) << 27); });
    EXPECT_NE(msg.find("data window 20000x6000 with 3 channels declares 1440000000 bytes of "
                       "pixels, over 10,000 times the file's " +
                       std::to_string(fs::file_size(forged)) + " bytes"),
              std::string::npos)
        << msg;
    if (msg.empty()) return;  // the loader would allocate 1.44 GB: not tried without the check
    const std::string frame = frameError((tmp.path / "f.####.exr").string(), 2);
    EXPECT_NE(frame.find("frame 2: " + forged.string() + ": data window 20000x6000"),
              std::string::npos)
        << frame;
    EXPECT_EQ(frameError((tmp.path / "f.####.exr").string(), 1), "");
}

// Issue 40 item 13: a camera.json matrix that places no camera (all zero; 1e308, which is inf as
// a float; beyond the loader's 1e30 bound) was used silently. Refused naming file, frame, key.
TEST(ExrLoaderRobustness, AbsurdCameraMatricesAreRefusedNamingFileAndFrame) {
    TempDir dir("exr-camera-absurd");
    const fs::path file = dir.path / "camera.json";
    const std::string identity = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
    auto write = [&](const std::string& view, const std::string& viewProjection) {
        std::ofstream(file) << R"({"resolution": [4, 4], "frames": [{"frame": 1, "view": )"
                            << identity << R"(, "view_projection": )" << identity
                            << R"(}, {"frame": 2, "view": )" << view << R"(, "view_projection": )"
                            << viewProjection << "}]}";
    };
    struct Case {
        std::string view, viewProjection, needle;
    };
    for (const auto& c : std::vector<Case>{
             {"[[0,0,0,0],[0,0,0,0],[0,0,0,0],[0,0,0,0]]", identity, "view has no inverse"},
             {"[[1e308,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]", identity, "view[0][0] is 1e+308"},
             {"[[1,0,0,-1e31],[0,1,0,0],[0,0,1,0],[0,0,0,1]]", identity, "view[0][3] is -1e+31"},
             {identity, "[[1,0,0,0],[0,1,0,0],[0,0,1e31,0],[0,0,0,1]]", "view_projection[2][2]"}}) {
        SCOPED_TRACE(c.needle);
        write(c.view, c.viewProjection);
        const std::string msg = errorOf([&] { kestrel::exr::BlenderCameras cameras(file); });
        for (const std::string& n : {file.string(), std::string("frame 2: "), c.needle})
            EXPECT_NE(msg.find(n), std::string::npos) << "'" << n << "' not in: " << msg;
    }
    write(identity, identity);
    EXPECT_EQ(errorOf([&] { kestrel::exr::BlenderCameras cameras(file); }), "");
    // Every shipped render's camera.json still loads.
    for (const char* name :
         {"blender-sample-room", "blender-showroom", "blender-street", "blender-street-defaults"}) {
        const std::string data = sharedData(name);
        if (data.empty()) continue;
        EXPECT_EQ(errorOf([&] { kestrel::exr::BlenderCameras cameras(data + "/camera.json"); }),
                  "");
    }
}

// Issue 40 item 13: a camera.json without an entry for a rendered frame gave that frame no
// camera matrices, with one warning. Refused before the run, naming file and frame.
TEST(ExrLoaderRobustness, CameraFileWithoutARenderedFrameIsRefusedBeforeTheRun) {
    const std::string data = sharedData("blender-sample-room");
    if (data.empty()) GTEST_SKIP() << "../shared/data/blender-sample-room not present";
    TempDir dir("exr-camera-gap");
    fs::create_directory(dir.path / "noisy");
    for (const char* f : {"frame_0001.exr", "frame_0002.exr", "frame_0003.exr"})
        fs::create_symlink(fs::path(data) / "noisy" / f, dir.path / "noisy" / f);
    // The shipped camera.json without its frame 3.
    std::ifstream in(data + "/camera.json");
    const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    auto doc = nlohmann::json::parse(text);
    auto& frames = doc["frames"];
    frames.erase(std::remove_if(frames.begin(), frames.end(),
                                [](const nlohmann::json& f) { return f["frame"] == 3; }),
                 frames.end());
    const fs::path camera = dir.path / "camera.json";
    std::ofstream(camera) << doc.dump();

    auto h = PassHarness::make<ExrLoader>(
        {1, 1}, {{"path", (dir.path / "noisy" / "frame_####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    kestrel::RunContext run;
    run.firstFrame = 1;
    run.lastFrame = 3;
    const std::string msg = errorOf([&] { h.pass().beginRun(run); });
    EXPECT_NE(msg.find("camera file " + camera.string() + " lists no frame 3"), std::string::npos)
        << msg;
    run.lastFrame = 2;  // the frames it lists run
    EXPECT_EQ(errorOf([&] { h.pass().beginRun(run); }), "");
    h.ctx.frameNumber = 3;  // a frame past the run's checked range still fails, as a frame
    std::string frameMsg;
    try {
        h.run();
    } catch (const kestrel::FrameError& e) {
        frameMsg = e.what();
    }
    EXPECT_NE(frameMsg.find("frame 3: camera file " + camera.string() + " lists no frame 3"),
              std::string::npos)
        << frameMsg;
}

// Blender's single-layer "OpenEXR" format holds Combined only (R, G, B, A): every G-buffer
// output it lacks says to save as OpenEXR MultiLayer, not which channel name is missing.
TEST(ExrLoaderRobustness, SingleLayerFileSaysSaveAsMultiLayer) {
    TempDir tmp("singlelayer");
    Channels ch = rgb(2, 2);
    ch["A"].assign(4, 1.f);
    writeExr(tmp.path / "b.0001.exr", box(0, 0, 1, 1), ch);
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "b.####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    ASSERT_EQ(rc.absent.count("depth"), 1u);
    EXPECT_EQ(rc.absent["depth"].rfind("a single-layer EXR (channels A, B, G, R) has no channel "
                                       "depth.Z: save the render as OpenEXR MultiLayer",
                                       0),
              0u)
        << rc.absent["depth"];
    EXPECT_NE(rc.absent["normal"].find("OpenEXR MultiLayer"), std::string::npos);
    EXPECT_EQ(rc.absent.count("color"), 0u);
}

// A bare Z (OpenEXR's convention for depth) is the depth of a single-layer file.
TEST(ExrLoaderRobustness, BareZChannelIsDepth) {
    TempDir tmp("barez");
    Channels ch = rgb(2, 2);
    ch["Z"] = {1.f, 2.f, 3.f, 4.f};
    writeExr(tmp.path / "b.0001.exr", box(0, 0, 1, 1), ch);
    auto h = PassHarness::make<ExrLoader>({2, 2}, {{"path", (tmp.path / "b.####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    ASSERT_EQ(rc.absent.count("depth"), 0u) << rc.absent["depth"];
    h.useOutputs({"color", "depth"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("depth").at(0, 1, 0), 2.f);
    EXPECT_EQ(h.out("depth").at(0, 1, 1), 4.f);
}

namespace {
/// A two-pixel Blender multilayer frame with view layers Day (colour 1) and Night (colour 5).
fs::path writeTwoLayers(const TempDir& tmp) {
    Channels ch;
    for (const auto& [layer, v] : {std::pair<std::string, float>{"Day", 1.f}, {"Night", 5.f}})
        for (const char* c : {"R", "G", "B"}) ch[layer + ".Combined." + c].assign(2, v);
    writeExr(tmp.path / "r.0001.exr", box(0, 0, 1, 0), ch);
    return tmp.path / "r.####.exr";
}
}  // namespace

// A render with several view layers: no silent pick of one; `layer` chooses, a wrong name lists
// them, and a layer choice on a file without view layers is refused rather than ignored.
TEST(ExrLoaderRobustness, SeveralViewLayersAreRefusedUnlessOneIsChosen) {
    TempDir tmp("layers");
    const fs::path pattern = writeTwoLayers(tmp);
    auto resolveError = [&](const std::map<std::string, kestrel::ParamValue>& params) {
        auto h = PassHarness::make<ExrLoader>({2, 1}, params);
        RecordingResolve rc(1);
        try {
            h.pass().resolve(rc);
        } catch (const kestrel::Error& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    const std::string none = resolveError({{"path", pattern.string()}});
    EXPECT_NE(none.find("has 2 view layers (Day, Night): choose one with the loader's layer "
                        "parameter (--set input.layer=Day)"),
              std::string::npos)
        << none;
    EXPECT_EQ(none.find('\n'), std::string::npos) << "one line: " << none;
    const std::string wrong = resolveError({{"path", pattern.string()}, {"layer", "Dusk"}});
    EXPECT_NE(wrong.find("layer 'Dusk': "), std::string::npos) << wrong;
    EXPECT_NE(wrong.find("has view layers Day, Night"), std::string::npos) << wrong;

    auto night =
        PassHarness::make<ExrLoader>({2, 1}, {{"path", pattern.string()}, {"layer", "Night"}});
    night.useOutputs({"color"});
    night.ctx.frameNumber = 1;
    night.run();
    EXPECT_EQ(night.out("color").at(0, 0, 0), 5.f);
    EXPECT_EQ(night.out("color").at(2, 1, 0), 5.f);

    writeExr(tmp.path / "c.0001.exr", box(0, 0, 1, 1), rgb(2, 2));
    const std::string canonical =
        resolveError({{"path", (tmp.path / "c.####.exr").string()}, {"layer", "Night"}});
    EXPECT_NE(canonical.find("is not a Blender multilayer EXR"), std::string::npos) << canonical;
}

// Cycles' Combined is RGBA: its A (the coverage, with Film > Transparent) is the alpha output.
TEST(ExrLoaderRobustness, BlenderCombinedAlphaIsTheAlphaOutput) {
    TempDir tmp("alpha");
    Channels ch;
    for (const char* c : {"R", "G", "B"}) ch[std::string("ViewLayer.Combined.") + c].assign(2, 1.f);
    ch["ViewLayer.Combined.A"] = {0.f, 0.5f};
    writeExr(tmp.path / "r.0001.exr", box(0, 0, 1, 0), ch);
    auto h = PassHarness::make<ExrLoader>({2, 1}, {{"path", (tmp.path / "r.####.exr").string()}});
    h.useOutputs({"color", "alpha"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("alpha").at(0, 0, 0), 0.f);
    EXPECT_EQ(h.out("alpha").at(0, 1, 0), 0.5f);
}

// A file merely named beauty.####.exr is one multi-channel frame; GAMES202's layout needs its
// other buffers (normal_, depth_) beside it. It used to be taken for the homework's layout.
TEST(ExrLoaderRobustness, FileNamedBeautyIsAFrameUnlessGames202BuffersLieBesideIt) {
    TempDir tmp("beautyname");
    Channels ch = rgb(2, 2);
    ch["Z"] = {1.f, 2.f, 3.f, 4.f};
    writeExr(tmp.path / "beauty.0001.exr", box(0, 0, 1, 1), ch);
    auto h =
        PassHarness::make<ExrLoader>({2, 2}, {{"path", (tmp.path / "beauty.####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.absent.count("color"), 0u) << rc.absent["color"];
    EXPECT_EQ(rc.absent.count("depth"), 0u) << rc.absent["depth"];
}

// A folder is GAMES202's layout only when it holds beauty_N.exr; any other folder is refused
// with the frame pattern its files suggest.
TEST(ExrLoaderRobustness, FolderWithoutGames202FilesSuggestsAPattern) {
    TempDir tmp("folderinput");
    writeExr(tmp.path / "shot_0007.exr", box(0, 0, 1, 1), rgb(2, 2));
    auto h = PassHarness::make<ExrLoader>({2, 2}, {{"path", tmp.path.string()}});
    RecordingResolve rc(1);
    const std::string msg = errorOf([&] { h.pass().resolve(rc); });
    EXPECT_NE(msg.find("is a folder without GAMES202's beauty_N.exr files: give a frame pattern "
                       "such as " +
                       (tmp.path / "shot_####.exr").string()),
              std::string::npos)
        << msg;
}
