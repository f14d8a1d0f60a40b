// The ZIP/ZIPS fast path (passes/exr/ZipScanlines.h) against OpenEXR's own reader: the same
// bits in every plane for every pixel type, window layout, line order and thread count, chunks
// stored uncompressed, and damaged files refused (so that the loader reads them through
// OpenEXR, which reports the damage). The writer's counterpart (ZipWriter.h): what it writes,
// OpenEXR reads back bit for bit.
#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>

#include "ExrInput.h"
#include "ExrLoader.h"
#include "ZipWriter.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

namespace {

using namespace kestrel::exr;
using exrtest::TempDir;
namespace fs = std::filesystem;

struct Spec {
    Imf::Compression compression = Imf::ZIP_COMPRESSION;
    Imath::Box2i data{{0, 0}, {0, 0}}, display{{0, 0}, {0, 0}};
    Imf::LineOrder order = Imf::INCREASING_Y;
    bool noise = true;   // random bits (incompressible); else smooth values (deflate shrinks them)
    bool mixed = false;  // b and c random, a and d smooth: deflated chunks of varied bytes
};

/// Writes channels "a" (HALF), "b" (FLOAT), "c" (UINT) and "d" (FLOAT). Noise includes NaN,
/// infinity and denormal bit patterns.
void writeFile(const std::string& path, const Spec& s) {
    Imf::Header h(s.display, s.data);
    h.compression() = s.compression;
    h.lineOrder() = s.order;
    h.channels().insert("a", Imf::Channel(Imf::HALF));
    h.channels().insert("b", Imf::Channel(Imf::FLOAT));
    h.channels().insert("c", Imf::Channel(Imf::UINT));
    h.channels().insert("d", Imf::Channel(Imf::FLOAT));
    const int w = s.data.max.x - s.data.min.x + 1, ht = s.data.max.y - s.data.min.y + 1;
    const size_t n = size_t(w) * size_t(ht);
    std::vector<uint16_t> a(n);
    std::vector<uint32_t> b(n), c(n), d(n);
    std::mt19937 rng(uint32_t(w * 131 + ht));
    for (size_t i = 0; i < n; ++i) {
        if (s.mixed) {
            const float v = float(i % size_t(w)) * 0.25f;
            a[i] = Imath::half(v).bits();
            b[i] = rng();
            c[i] = rng();
            std::memcpy(&d[i], &v, 4);
        } else if (s.noise) {
            a[i] = uint16_t(rng());
            b[i] = rng();
            c[i] = rng();
            d[i] = rng();
        } else {
            float v = float(i % size_t(w)) * 0.25f;
            Imath::half hv(v);
            a[i] = hv.bits();
            std::memcpy(&b[i], &v, 4);
            c[i] = uint32_t(i / size_t(w));
            v = 1.f / (1.f + float(i));
            std::memcpy(&d[i], &v, 4);
        }
    }
    Imf::FrameBuffer fb;
    const ptrdiff_t origin = s.data.min.x + ptrdiff_t(s.data.min.y) * w;
    auto slice = [&](Imf::PixelType t, void* p, size_t size) {
        return Imf::Slice(t, static_cast<char*>(p) - origin * ptrdiff_t(size), size,
                          size * size_t(w));
    };
    fb.insert("a", slice(Imf::HALF, a.data(), 2));
    fb.insert("b", slice(Imf::FLOAT, b.data(), 4));
    fb.insert("c", slice(Imf::UINT, c.data(), 4));
    fb.insert("d", slice(Imf::FLOAT, d.data(), 4));
    Imf::OutputFile out(path.c_str(), h);
    out.setFrameBuffer(fb);
    out.writePixels(ht);
}

using Planes = std::vector<std::vector<float>>;
const float kUntouched = -12345.f;  // outside the data window: neither reader writes there

/// Channels b, a, c (in that order) and "missing" (not in the file, fill 7), over the display.
Planes readByOpenExr(const std::string& path, const Box& dp) {
    const int W = int(dp.width());
    const size_t N = size_t(W) * size_t(dp.height());
    Planes p(4, std::vector<float>(N, kUntouched));
    std::fill(p[3].begin(), p[3].end(), 7.f);  // OpenEXR fills the rows it reads; these fill all
    Imf::InputFile f(path.c_str());
    const Imath::Box2i dw = f.header().dataWindow();
    const int ix0 = std::max(dw.min.x, dp.x0), ix1 = std::min(dw.max.x, dp.x1);
    const int iy0 = std::max(dw.min.y, dp.y0), iy1 = std::min(dw.max.y, dp.y1);
    if (ix0 > ix1 || iy0 > iy1) return p;
    // Read the whole data window into a buffer, then keep the part inside the display.
    const int w = dw.max.x - dw.min.x + 1, ht = dw.max.y - dw.min.y + 1;
    const char* names[] = {"b", "a", "c"};
    Planes full(3, std::vector<float>(size_t(w) * size_t(ht)));
    Imf::FrameBuffer fb;
    const ptrdiff_t origin = dw.min.x + ptrdiff_t(dw.min.y) * w;
    for (int k = 0; k < 3; ++k)
        fb.insert(names[k], Imf::Slice(Imf::FLOAT, (char*)(full[size_t(k)].data() - origin), 4,
                                       4 * size_t(w)));
    f.setFrameBuffer(fb);
    f.readPixels(dw.min.y, dw.max.y);
    for (int k = 0; k < 3; ++k)
        for (int y = iy0; y <= iy1; ++y)
            for (int x = ix0; x <= ix1; ++x)
                p[size_t(k)][size_t(y - dp.y0) * size_t(W) + size_t(x - dp.x0)] =
                    full[size_t(k)][size_t(y - dw.min.y) * size_t(w) + size_t(x - dw.min.x)];
    return p;
}

Planes readFast(const std::string& path, const Box& dp, int threads, ZipScanlines::Stats* stats,
                bool* ok = nullptr, std::string* why = nullptr, const Workspace& lent = {}) {
    ExrInput in(path, int64_t(1) << 27);
    EXPECT_NE(in.zip(), nullptr) << path;
    const int W = int(dp.width());
    const size_t N = size_t(W) * size_t(dp.height());
    Planes p(4, std::vector<float>(N, kUntouched));
    if (!in.zip()) return p;
    std::vector<std::pair<std::string, float*>> chans = {
        {"b", p[0].data()}, {"a", p[1].data()}, {"c", p[2].data()}, {"missing", p[3].data()}};
    std::string reason;
    const bool good =
        in.zip()->decode(dp, W, chans, {0.f, 0.f, 0.f, 7.f}, threads, &reason, stats, lent);
    if (ok) *ok = good;
    if (why) *why = reason;
    if (!ok) {
        EXPECT_TRUE(good) << reason;
    }
    return p;
}

void expectSameBits(const Planes& want, const Planes& got, const std::string& what) {
    ASSERT_EQ(want.size(), got.size());
    for (size_t k = 0; k < want.size(); ++k) {
        ASSERT_EQ(want[k].size(), got[k].size());
        size_t diff = 0, first = 0;
        for (size_t i = 0; i < want[k].size(); ++i)
            if (std::memcmp(&want[k][i], &got[k][i], 4) != 0 && diff++ == 0) first = i;
        EXPECT_EQ(diff, 0u) << what << ": plane " << k << ", first at " << first;
    }
}

Box toBox(const Imath::Box2i& b) {
    return {b.min.x, b.min.y, b.max.x, b.max.y};
}

TEST(ZipScanlines, SameBitsAsOpenExrForEveryLayout) {
    TempDir dir("zipfast");
    struct Case {
        const char* what;
        Spec spec;
    };
    const Case cases[] = {
        {"ZIP 37x35 (a partial last chunk)",
         {Imf::ZIP_COMPRESSION, {{0, 0}, {36, 34}}, {{0, 0}, {36, 34}}}},
        {"ZIPS 37x35", {Imf::ZIPS_COMPRESSION, {{0, 0}, {36, 34}}, {{0, 0}, {36, 34}}}},
        {"ZIP smooth 300x40",
         {Imf::ZIP_COMPRESSION,
          {{0, 0}, {299, 39}},
          {{0, 0}, {299, 39}},
          Imf::INCREASING_Y,
          false}},
        {"ZIP decreasing y",
         {Imf::ZIP_COMPRESSION, {{0, 0}, {40, 50}}, {{0, 0}, {40, 50}}, Imf::DECREASING_Y, false}},
        {"ZIP 53x41, half noise",
         {Imf::ZIP_COMPRESSION,
          {{0, 0}, {52, 40}},
          {{0, 0}, {52, 40}},
          Imf::INCREASING_Y,
          false,
          true}},
        {"ZIPS 53x41, half noise",
         {Imf::ZIPS_COMPRESSION,
          {{0, 0}, {52, 40}},
          {{0, 0}, {52, 40}},
          Imf::INCREASING_Y,
          false,
          true}},
        {"ZIP 1x1", {Imf::ZIP_COMPRESSION, {{0, 0}, {0, 0}}, {{0, 0}, {0, 0}}}},
        {"data window inside the display",
         {Imf::ZIP_COMPRESSION, {{5, 3}, {30, 40}}, {{0, 0}, {47, 49}}, Imf::INCREASING_Y, false}},
        {"data window beyond the display, negative origin",
         {Imf::ZIP_COMPRESSION, {{-9, -20}, {50, 33}}, {{0, 0}, {39, 29}}}},
        {"display with a non-zero origin",
         {Imf::ZIPS_COMPRESSION,
          {{10, 10}, {60, 44}},
          {{20, 12}, {70, 40}},
          Imf::INCREASING_Y,
          false}},
        {"no overlap", {Imf::ZIP_COMPRESSION, {{100, 100}, {120, 130}}, {{0, 0}, {19, 9}}}},
    };
    for (const Case& c : cases) {
        const std::string path = (dir.path / "f.exr").string();
        writeFile(path, c.spec);
        const Box dp = toBox(c.spec.display);
        const Planes want = readByOpenExr(path, dp);
        for (int threads : {1, 2, 5}) {
            ZipScanlines::Stats stats;
            const Planes got = readFast(path, dp, threads, &stats);
            if (c.spec.mixed) {  // the predictor's path, on varied bytes
                EXPECT_EQ(stats.stored, 0) << c.what;
            }
            expectSameBits(want, got,
                           std::string(c.what) + ", " + std::to_string(threads) + " threads");
        }
    }
}

TEST(ZipScanlines, DecodesInLentMemoryWhereARegionHoldsAChunk) {
    // The loader lends the graph's idle planes (PassIO::idlePlanes): two per decoding thread
    // where each holds a chunk (16 lines of a, b, c, d: 14 bytes per pixel), else the thread
    // maps its own buffers. Same bits either way.
    TempDir dir("ziplent");
    const std::string path = (dir.path / "f.exr").string();
    Spec s{Imf::ZIP_COMPRESSION, {{0, 0}, {299, 39}}, {{0, 0}, {299, 39}}};
    s.mixed = true;  // deflated chunks: both buffers in use
    writeFile(path, s);
    const Box dp = toBox(s.display);
    const Planes want = readByOpenExr(path, dp);
    const size_t chunkBytes = 16 * 300 * 14;
    constexpr float kSentinel = -12345.f;
    for (const size_t regionFloats : {chunkBytes / 4, chunkBytes / 4 - 1})
        for (const int threads : {3, 2}) {
            std::vector<std::vector<float>> regions(5, std::vector<float>(regionFloats, kSentinel));
            std::vector<float*> pointers;
            for (auto& r : regions) pointers.push_back(r.data());
            const Workspace lent{pointers, regionFloats * sizeof(float)};
            ZipScanlines::Stats stats;
            const std::string what = std::to_string(regionFloats) + " floats per region, " +
                                     std::to_string(threads) + " threads";
            expectSameBits(want, readFast(path, dp, threads, &stats, nullptr, nullptr, lent), what);
            EXPECT_EQ(stats.stored, 0);
            const bool fits = regionFloats * sizeof(float) >= chunkBytes;
            // Threads 0 and 1 decode in regions 0-3 when they fit; region 4 is never lent. With 3
            // threads, thread 2 has no pair and maps its own, and on a busy machine it may take
            // every chunk, so only 2 threads must use the regions.
            size_t written = 0;
            for (size_t k = 0; k < 4; ++k) written += regions[k][0] != kSentinel;
            if (!fits || threads == 2) {
                EXPECT_EQ(written > 0, fits) << what;
            }
            EXPECT_EQ(regions[4][0], kSentinel) << what;
        }
}

TEST(ZipScanlines, ChunksStoredUncompressedAndDeflatedBothDecode) {
    // Random bits do not deflate: OpenEXR stores such chunks as they are; smooth values deflate.
    TempDir dir("zipraw");
    const std::string path = (dir.path / "f.exr").string();
    for (bool noise : {true, false}) {
        Spec s{
            Imf::ZIPS_COMPRESSION, {{0, 0}, {63, 7}}, {{0, 0}, {63, 7}}, Imf::INCREASING_Y, noise};
        writeFile(path, s);
        ZipScanlines::Stats stats;
        const Planes got = readFast(path, toBox(s.display), 2, &stats);
        expectSameBits(readByOpenExr(path, toBox(s.display)), got, noise ? "noise" : "smooth");
        EXPECT_EQ(stats.chunks, 8);
        if (noise)
            EXPECT_EQ(stats.stored, 8) << "every chunk of noise is kept uncompressed";
        else
            EXPECT_EQ(stats.stored, 0) << "every smooth chunk deflates";
    }
}

TEST(ZipScanlines, OnlyZipScanlineFilesTakeTheFastPath) {
    TempDir dir("zipelig");
    const Imath::Box2i dw{{0, 0}, {15, 15}};
    exrtest::Channels ch{{"R", std::vector<float>(256, 0.5f)}};
    struct Case {
        Imf::Compression c;
        bool tiled, fast;
    };
    for (const Case& c :
         {Case{Imf::ZIP_COMPRESSION, false, true}, Case{Imf::ZIPS_COMPRESSION, false, true},
          Case{Imf::PIZ_COMPRESSION, false, false}, Case{Imf::NO_COMPRESSION, false, false},
          Case{Imf::ZIP_COMPRESSION, true, false}}) {
        const fs::path p = dir.path / "e.exr";
        exrtest::WriteOptions o;
        o.compression = c.c;
        o.tiled = c.tiled;
        exrtest::writeExr(p, dw, ch, o);
        ExrInput in(p.string(), int64_t(1) << 27);
        EXPECT_EQ(in.zip() != nullptr, c.fast)
            << "compression " << int(c.c) << (c.tiled ? " tiled" : "");
    }
}

/// The file's bytes with `edit` applied.
void rewrite(const std::string& path, const std::function<void(std::string&)>& edit) {
    std::string bytes;
    {
        std::ifstream f(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(f), {});
    }
    edit(bytes);
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        .write(bytes.data(), std::streamsize(bytes.size()));
}

// The 4-entry offset table of the files below: its first entry points right past it.
size_t tablePos(const std::string& b) {
    for (size_t p = 8; p + 8 <= b.size(); ++p) {
        uint64_t v;
        std::memcpy(&v, b.data() + p, 8);
        if (v == p + 32) return p;
    }
    ADD_FAILURE() << "no offset table found";
    return 0;
}
void setOffset(std::string& b, int i, uint64_t v) {
    std::memcpy(b.data() + tablePos(b) + size_t(i) * 8, &v, 8);
}

TEST(ZipScanlines, DamagedChunksAreRefusedWithTheChunkNamed) {
    TempDir dir("zipbad");
    const std::string path = (dir.path / "f.exr").string();
    const Spec s{
        Imf::ZIP_COMPRESSION, {{0, 0}, {99, 63}}, {{0, 0}, {99, 63}}, Imf::INCREASING_Y, false};
    struct Case {
        const char* what;
        std::function<void(std::string&)> edit;
        const char* reason;
    };
    // The chunks follow the header and the 4-entry offset table; the last chunk ends the file.
    const Case cases[] = {
        {"a flipped byte in the last chunk's deflate stream",
         [](std::string& b) { b[b.size() - 40] = char(b[b.size() - 40] ^ 0x5a); }, "chunk 3"},
        {"the file cut short", [](std::string& b) { b.resize(b.size() - 10); }, "chunk 3"},
        {"the first offset past the end of the file",
         [](std::string& b) { setOffset(b, 0, b.size() + 5); }, "chunk 0: offset"},
        {"the first offset into the header", [](std::string& b) { setOffset(b, 0, 8); },
         "chunk 0: offset"},
        {"the last offset into the header (the chunk before it ends elsewhere)",
         [](std::string& b) { setOffset(b, 3, 8); },
         "chunk 2: the next chunk in the file is not where the offset table puts it"},
        {"a chunk read from elsewhere than after the one before it (OpenEXR would not)",
         [](std::string& b) {
             // A copy of chunk 1 appended at the end, and entry 1 pointing to it.
             const size_t p = tablePos(b);
             uint64_t o1, o2;
             std::memcpy(&o1, b.data() + p + 8, 8);
             std::memcpy(&o2, b.data() + p + 16, 8);
             const std::string copy = b.substr(size_t(o1), size_t(o2 - o1));
             setOffset(b, 1, b.size());
             b += copy;
         },
         "chunk 0: the next chunk in the file is not where the offset table puts it"},
        {"two entries swapped (a chunk's line number is not its place)",
         [](std::string& b) {
             const size_t p = tablePos(b);
             std::swap_ranges(b.begin() + ptrdiff_t(p), b.begin() + ptrdiff_t(p + 8),
                              b.begin() + ptrdiff_t(p + 8));
         },
         "chunk 0: starts at line 16, expected 0"},
    };
    for (const Case& c : cases) {
        writeFile(path, s);
        rewrite(path, c.edit);
        bool ok = true;
        std::string why;
        readFast(path, toBox(s.display), 1, nullptr, &ok, &why);  // 1 thread: chunks in order
        EXPECT_FALSE(ok) << c.what;
        EXPECT_NE(why.find(c.reason), std::string::npos) << c.what << ": " << why;
    }
}

TEST(ZipScanlines, TheLoaderFallsBackToOpenExrWhichRepairsAMissingOffset) {
    // A file whose writer died before its offset table was filled has zeros there; OpenEXR
    // rebuilds the table by walking the chunks, the fast path refuses it: the loader's planes
    // must be those of the intact file.
    TempDir dir("zipfallback");
    exrtest::Channels ch;
    for (const char* n : {"R", "G", "B"}) {
        auto& v = ch[n];
        for (int i = 0; i < 40 * 50; ++i) v.push_back(float(i % 97) * 0.01f + float(n[0]));
    }
    const Imath::Box2i dw{{0, 0}, {39, 49}};
    exrtest::writeExr(dir.path / "f.0001.exr", dw, ch);
    exrtest::writeExr(dir.path / "f.0002.exr", dw, ch);
    rewrite((dir.path / "f.0002.exr").string(), [](std::string& b) { setOffset(b, 1, 0); });
    ASSERT_EQ(ExrInput((dir.path / "f.0002.exr").string(), int64_t(1) << 27).zip(), nullptr)
        << "a zeroed entry leaves the file to OpenEXR";
    auto h = kestrel::testing::PassHarness::make<ExrLoader>(
        {1, 1}, {{"path", (dir.path / "f.####.exr").string()}});
    h.useOutputs({"color"});
    std::vector<std::vector<float>> frames;
    for (int f : {1, 2}) {
        h.ctx.frameNumber = f;
        h.run();
        for (int c = 0; c < 3; ++c) {
            const float* p = h.out("color").channel(c);
            frames.emplace_back(p, p + 40 * 50);
        }
    }
    for (int c = 0; c < 3; ++c)
        EXPECT_EQ(frames[size_t(c)], frames[size_t(3 + c)]) << "channel " << c;
}

/// Writes `values` (per channel, W x H) with writeZipScanlines and reads every channel back
/// through OpenEXR as stored (half as half bits, float as float bits).
void roundTrip(const std::string& path, int W, int H, Imf::Compression c, int threads, int level,
               const std::vector<std::pair<std::string, Imf::PixelType>>& channels, bool noise) {
    Imf::Header h(W, H);
    h.compression() = c;
    std::vector<std::vector<uint32_t>> data;  // float bits, or half bits in the low 16
    std::mt19937 rng(uint32_t(W * 7 + H));
    std::vector<const void*> planes;
    std::vector<std::vector<uint16_t>> halves;
    halves.reserve(channels.size());
    std::map<std::string, std::pair<Imf::PixelType, const void*>> byName;
    for (const auto& [name, type] : channels) {
        h.channels().insert(name, Imf::Channel(type));
        auto& v = data.emplace_back(size_t(W) * size_t(H));
        for (size_t i = 0; i < v.size(); ++i) {
            float f = float(i % size_t(W)) * 0.5f + float(i / size_t(W));
            uint32_t bits;
            std::memcpy(&bits, &f, 4);
            v[i] = noise ? rng() : bits;
            if (type == Imf::HALF) v[i] = noise ? (v[i] & 0xffff) : Imath::half(f).bits();
        }
        if (type == Imf::HALF) {
            halves.emplace_back(v.begin(), v.end());
            byName[name] = {type, halves.back().data()};
        } else {
            byName[name] = {type, v.data()};
        }
    }
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it)
        planes.push_back(byName[it.name()].second);
    writeZipScanlines(path, h, planes, threads, level);
    if (noise) {  // random bits do not deflate: every chunk is stored as it is
        size_t raw = 0;
        for (const auto& [name, type] : channels)
            raw += size_t(W) * size_t(H) * (type == Imf::HALF ? 2 : 4);
        EXPECT_GT(fs::file_size(path), raw);
    }

    Imf::InputFile in(path.c_str());
    EXPECT_EQ(in.header().compression(), c);
    Imf::FrameBuffer fb;
    std::vector<std::vector<uint32_t>> back(channels.size(),
                                            std::vector<uint32_t>(size_t(W) * size_t(H)));
    std::vector<std::vector<uint16_t>> backHalf(channels.size(),
                                                std::vector<uint16_t>(size_t(W) * size_t(H)));
    for (size_t k = 0; k < channels.size(); ++k) {
        const auto& [name, type] = channels[k];
        char* base = type == Imf::HALF ? reinterpret_cast<char*>(backHalf[k].data())
                                       : reinterpret_cast<char*>(back[k].data());
        const size_t e = type == Imf::HALF ? 2 : 4;
        fb.insert(name, Imf::Slice(type, base, e, e * size_t(W)));
    }
    in.setFrameBuffer(fb);
    in.readPixels(0, H - 1);
    for (size_t k = 0; k < channels.size(); ++k) {
        size_t diff = 0;
        for (size_t i = 0; i < data[k].size(); ++i) {
            const uint32_t got = channels[k].second == Imf::HALF ? backHalf[k][i] : back[k][i];
            diff += got != data[k][i];
        }
        EXPECT_EQ(diff, 0u) << channels[k].first << " " << W << "x" << H << " compression "
                            << int(c) << " level " << level << (noise ? " noise" : "");
    }
}

TEST(ZipWriter, OpenExrReadsBackEveryValue) {
    TempDir dir("zipwrite");
    const std::string path = (dir.path / "w.exr").string();
    const std::vector<std::pair<std::string, Imf::PixelType>> rgba = {
        {"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"A", Imf::HALF}};
    const std::vector<std::pair<std::string, Imf::PixelType>> mixed = {
        {"id", Imf::FLOAT}, {"Z", Imf::FLOAT}, {"Y", Imf::HALF}};
    for (Imf::Compression c : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION})
        for (bool noise : {false, true})
            for (auto [W, H] : {std::pair{1, 1}, std::pair{37, 35}, std::pair{320, 40}}) {
                roundTrip(path, W, H, c, 2, 4, rgba, noise);
                roundTrip(path, W, H, c, 3, 1, mixed, noise);
            }
    roundTrip(path, 64, 48, Imf::ZIP_COMPRESSION, 1, 12, rgba, false);
}

/// A 123 x 77 ZIP image of two HALF channels: B a ramp along x, G falling with the index.
struct HalfImage {
    Imf::Header header{123, 77};
    std::vector<uint16_t> b = std::vector<uint16_t>(123 * 77), g = std::vector<uint16_t>(123 * 77);
    HalfImage() {
        header.compression() = Imf::ZIP_COMPRESSION;
        header.channels().insert("B", Imf::Channel(Imf::HALF));
        header.channels().insert("G", Imf::Channel(Imf::HALF));
        for (size_t i = 0; i < b.size(); ++i) {
            b[i] = Imath::half(float(i % 123) * 0.1f).bits();
            g[i] = Imath::half(1.f / float(1 + i)).bits();
        }
    }
};

TEST(ZipWriter, OutputDoesNotDependOnTheThreadCountAndItsOwnReaderAgrees) {
    TempDir dir("zipwrite2");
    const HalfImage img;
    const Imf::Header& h = img.header;
    const std::vector<uint16_t>&b = img.b, &g = img.g;
    std::string bytes[2];
    int k = 0;
    for (int threads : {1, 4}) {
        const std::string path = (dir.path / ("t" + std::to_string(threads) + ".exr")).string();
        writeZipScanlines(path, h, {b.data(), g.data()}, threads, 4);
        std::ifstream f(path, std::ios::binary);
        bytes[k++].assign(std::istreambuf_iterator<char>(f), {});
    }
    EXPECT_EQ(bytes[0], bytes[1]) << "the file's bytes are those of one thread";
    const std::string path = (dir.path / "t1.exr").string();
    ExrInput in(path, int64_t(1) << 27);
    ASSERT_NE(in.zip(), nullptr);
    std::vector<float> fb(123 * 77), fg(123 * 77);
    std::string why;
    ASSERT_TRUE(in.zip()->decode({0, 0, 122, 76}, 123, {{"B", fb.data()}, {"G", fg.data()}},
                                 {0.f, 0.f}, 2, &why))
        << why;
    auto widen = [](uint16_t bits) {
        Imath::half v;
        v.setBits(bits);
        return float(v);
    };
    for (size_t i = 0; i < b.size(); ++i) {
        ASSERT_EQ(fb[i], widen(b[i])) << i;
        ASSERT_EQ(fg[i], widen(g[i])) << i;
    }
}

TEST(ZipWriter, EncodesInLentMemoryWhenThereIsEnoughOfIt) {
    // The writer's chunk buffers (two per thread, one per chunk of a batch) go in the regions the
    // ExrWriter lends (its idle planes) when there are enough that hold a chunk: 16 lines of two
    // half channels, 123 wide. Same bytes either way.
    TempDir dir("ziplentw");
    const HalfImage img;
    const Imf::Header& h = img.header;
    const std::vector<uint16_t>&b = img.b, &g = img.g;
    auto write = [&](const std::string& name, const Workspace& lent) {
        const std::string path = (dir.path / name).string();
        writeZipScanlines(path, h, {b.data(), g.data()}, 2, 4, {}, lent);
        std::ifstream f(path, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(f), {});
    };
    const std::string plain = write("plain.exr", {});
    const size_t chunkFloats = 16 * 123 * 4 / 4;
    constexpr float kSentinel = -12345.f;
    struct Case {
        size_t regions, floats;
        bool used;
    };
    // Two threads need 2 x 2 + 2 regions at least (a batch of two chunks); smaller regions or
    // fewer of them are not used.
    for (const Case c : {Case{12, chunkFloats, true}, Case{6, chunkFloats, true},
                         Case{5, chunkFloats, false}, Case{12, chunkFloats - 1, false}}) {
        std::vector<std::vector<float>> regions(c.regions, std::vector<float>(c.floats, kSentinel));
        std::vector<float*> pointers;
        for (auto& r : regions) pointers.push_back(r.data());
        const std::string what =
            std::to_string(c.regions) + " regions of " + std::to_string(c.floats) + " floats";
        EXPECT_EQ(write("lent.exr", {pointers, c.floats * sizeof(float)}), plain) << what;
        size_t written = 0;
        for (const auto& r : regions) written += r[0] != kSentinel;
        EXPECT_EQ(written > 0, c.used) << what;
    }
}

// The writer streams: a scan line is asked for when its chunk is encoded, and chunks are written a
// batch at a time (a few per thread), so it never holds a frame-sized copy or the whole frame's
// encoded chunks. When the first chunk is on disk, only the first batch's rows were asked for;
// every row of every channel is asked for exactly once; the file reads back.
TEST(ZipWriter, StreamsRowsAndChunksABatchAtATime) {
    TempDir dir("zipstream");
    constexpr int W = 40, H = 1024;  // 64 chunks of 16 lines
    Imf::Header h(W, H);
    h.compression() = Imf::ZIP_COMPRESSION;
    h.channels().insert("G", Imf::Channel(Imf::FLOAT));
    h.channels().insert("R", Imf::Channel(Imf::FLOAT));
    std::vector<std::atomic<int>> asked(2 * size_t(H));
    std::atomic<size_t> rowsAsked{0};
    const ZipRowSource rows = [&](size_t c, size_t row, unsigned char* dst) {
        ++asked[c * H + row];
        ++rowsAsked;
        for (int x = 0; x < W; ++x) {
            const float v = float(c) * 1000.f + float(row) + 0.25f * float(x);
            std::memcpy(dst + 4 * size_t(x), &v, 4);
        }
    };
    size_t askedAtFirstChunk = 0;
    const std::string path = (dir.path / "stream.exr").string();
    writeZipScanlines(path, h, rows, 2, 4, [&](size_t written) {
        if (written == 1) askedAtFirstChunk = rowsAsked;
    });
    EXPECT_GT(askedAtFirstChunk, 0u);
    EXPECT_LE(askedAtFirstChunk, 2u * 16u * 8u) << "more than a batch (8 chunks) encoded first";
    for (size_t i = 0; i < asked.size(); ++i) ASSERT_EQ(asked[i], 1) << "row " << i % H;
    Imf::InputFile in(path.c_str());
    std::vector<float> g(size_t(W) * H), r(size_t(W) * H);
    Imf::FrameBuffer fb;
    fb.insert("G", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(g.data()), 4, 4 * W));
    fb.insert("R", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(r.data()), 4, 4 * W));
    in.setFrameBuffer(fb);
    in.readPixels(0, H - 1);
    for (int y = 0; y < H; y += 37)
        for (int x = 0; x < W; x += 7) {
            EXPECT_EQ(g[size_t(y) * W + x], float(y) + 0.25f * float(x));
            EXPECT_EQ(r[size_t(y) * W + x], 1000.f + float(y) + 0.25f * float(x));
        }
}

TEST(ZipScanlines, WindowsWiderThanAnIntAreRefusedWhateverMaxPixels) {
    // With maxPixels raised to 2^33, a data window from INT_MIN to INT_MAX (2^32 pixels in one
    // row) passes the pixel limit; its width would overflow the decoders' int offsets.
    TempDir dir("zipwide");
    const std::string path = (dir.path / "w.exr").string();
    writeFile(path, {Imf::ZIPS_COMPRESSION, {{0, 0}, {7, 0}}, {{0, 0}, {7, 0}}});
    rewrite(path, [](std::string& b) {
        const std::string key = std::string("dataWindow") + '\0' + "box2i" + '\0';
        const size_t at = b.find(key);
        ASSERT_NE(at, std::string::npos);
        const int32_t box[4] = {std::numeric_limits<int32_t>::min(), 0,
                                std::numeric_limits<int32_t>::max(), 0};
        std::memcpy(b.data() + at + key.size() + 4, box, 16);
    });
    try {
        ExrInput in(path, int64_t(1) << 33);
        ADD_FAILURE() << "opened";
    } catch (const kestrel::Error& e) {
        EXPECT_NE(std::string(e.what()).find("spans more than 2^31 - 1 pixels"), std::string::npos)
            << e.what();
    }
}

}  // namespace
