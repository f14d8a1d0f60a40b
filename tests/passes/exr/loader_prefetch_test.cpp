// ExrLoader's read-ahead ("prefetch") and OpenEXR's thread pool: the frames are the same with
// and without them, and a bad frame is reported when it is reached, not when it is read ahead.
#include <OpenEXR/ImfThreading.h>
#include <gtest/gtest.h>

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

/// Noise (compresses badly: many ZIP blocks of real data), different per frame.
Channels noise(int w, int h, uint32_t seed) {
    Channels ch;
    uint32_t s = seed * 2654435761u + 1;
    for (const char* n : {"R", "G", "B"}) {
        auto& v = ch[n];
        v.resize(size_t(w) * size_t(h));
        for (auto& x : v) x = float((s = s * 1664525u + 1013904223u) >> 8) / float(1 << 24);
    }
    return ch;
}

/// Frames first..last of `pattern` through one loader; each frame's color planes, or the
/// FrameError message for a frame that failed.
struct Frames {
    std::vector<std::vector<float>> planes;
    std::vector<std::string> errors;
};
Frames runFrames(const std::string& pattern, int64_t first, int64_t last, bool prefetch,
                 int threads = 1) {
    auto h =
        PassHarness::make<ExrLoader>({1, 1}, {{"path", pattern}, {"prefetch", prefetch}}, threads);
    RecordingResolve rc(first);
    h.pass().resolve(rc);
    h.pass().beginRun(kestrel::RunContext{nullptr, first, last});
    h.useOutputs({"color"});
    h.ctx.frameNumber = first;
    Frames r;
    for (int64_t f = first; f <= last; ++f) {
        h.ctx.frameNumber = f;
        std::string err;
        try {
            h.run();
        } catch (const kestrel::FrameError& e) {
            err = e.what();
        }
        r.errors.push_back(err);
        std::vector<float> v;
        if (err.empty()) {
            const auto& img = h.out("color");
            const size_t n = size_t(img.width()) * size_t(img.height());
            for (int c = 0; c < 3; ++c) v.insert(v.end(), img.channel(c), img.channel(c) + n);
        }
        r.planes.push_back(std::move(v));
    }
    h.pass().endRun();
    return r;
}

bool sameBits(const std::vector<float>& a, const std::vector<float>& b) {
    // Empty planes (a frame that failed) have null data(), which memcmp must not be given.
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * 4) == 0);
}
}  // namespace

TEST(ExrLoaderPrefetch, PrefetchedFramesAreIdenticalToUnprefetched) {
    TempDir tmp("prefetch_same");
    WriteOptions opt;
    opt.display = box(0, 0, 95, 79);  // the data window lies inside: fill values around it
    for (int f = 1; f <= 5; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "f.%04d.exr", f);
        writeExr(tmp.path / name, box(2, 3, 90, 77), noise(89, 75, uint32_t(f)), opt);
    }
    const std::string pattern = (tmp.path / "f.####.exr").string();
    Frames off = runFrames(pattern, 1, 5, false), on = runFrames(pattern, 1, 5, true);
    for (size_t i = 0; i < 5; ++i) {
        EXPECT_EQ(off.errors[i], "");
        EXPECT_EQ(on.errors[i], "");
        EXPECT_EQ(on.planes[i].size(), size_t(96 * 80 * 3));
        EXPECT_TRUE(sameBits(off.planes[i], on.planes[i])) << "frame " << i + 1;
    }
    EXPECT_FALSE(sameBits(on.planes[0], on.planes[1]));  // the frames do differ
}

TEST(ExrLoaderPrefetch, BadNextFrameIsReportedWhenReachedAndTheRunGoesOn) {
    TempDir tmp("prefetch_bad");
    for (int f : {1, 2, 4, 5}) {
        char name[32];
        std::snprintf(name, sizeof name, "f.%04d.exr", f);
        writeExr(tmp.path / name, box(0, 0, 31, 23), noise(32, 24, uint32_t(f)));
    }
    std::ofstream(tmp.path / "f.0003.exr") << "this is not an EXR file at all";
    const std::string pattern = (tmp.path / "f.####.exr").string();
    Frames off = runFrames(pattern, 1, 5, false), on = runFrames(pattern, 1, 5, true);
    // Frame 2 (which read frame 3 ahead) succeeds; frame 3 fails naming its file, with the same
    // message as without prefetch; frames 4 and 5 load (what --skip-bad-frames relies on).
    for (size_t i : {0u, 1u, 3u, 4u}) {
        EXPECT_EQ(on.errors[i], "") << "frame " << i + 1;
        EXPECT_TRUE(sameBits(off.planes[i], on.planes[i])) << "frame " << i + 1;
    }
    EXPECT_NE(on.errors[2].find("frame 3"), std::string::npos) << on.errors[2];
    EXPECT_NE(on.errors[2].find("f.0003.exr"), std::string::npos) << on.errors[2];
    EXPECT_EQ(on.errors[2], off.errors[2]);
}

TEST(ExrLoaderPrefetch, MissingNextFrameIsReportedWhenReached) {
    TempDir tmp("prefetch_missing");
    for (int f : {1, 2}) {
        char name[32];
        std::snprintf(name, sizeof name, "f.%04d.exr", f);
        writeExr(tmp.path / name, box(0, 0, 15, 15), noise(16, 16, uint32_t(f)));
    }
    Frames on = runFrames((tmp.path / "f.####.exr").string(), 1, 3, true);
    EXPECT_EQ(on.errors[0], "");
    EXPECT_EQ(on.errors[1], "");
    EXPECT_NE(on.errors[2].find("f.0003.exr"), std::string::npos) << on.errors[2];
}

TEST(ExrLoaderPrefetch, ThreadedDecodingIsBitIdenticalToOneThread) {
    TempDir tmp("prefetch_threads");
    for (int f = 1; f <= 2; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "f.%04d.exr", f);
        writeExr(tmp.path / name, box(0, 0, 255, 199), noise(256, 200, uint32_t(f)));
    }
    const std::string pattern = (tmp.path / "f.####.exr").string();
    Imf::setGlobalThreadCount(0);  // the pool only grows: start without one
    Frames one = runFrames(pattern, 1, 2, false, 1);
    EXPECT_EQ(Imf::globalThreadCount(), 1);
    Frames four = runFrames(pattern, 1, 2, true, 4);
    EXPECT_EQ(Imf::globalThreadCount(), 4);
    for (size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(one.errors[i], "");
        EXPECT_EQ(four.errors[i], "");
        EXPECT_TRUE(sameBits(one.planes[i], four.planes[i])) << "frame " << i + 1;
    }
}

TEST(ExrLoaderPrefetch, DestroyedWhileReadingAheadJoinsCleanly) {
    TempDir tmp("prefetch_destroy");
    for (int f = 1; f <= 2; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "f.%04d.exr", f);
        writeExr(tmp.path / name, box(0, 0, 255, 199), noise(256, 200, uint32_t(f)));
    }
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    h.useOutputs({"color"});
    h.ctx.frameNumber = 1;
    h.run();  // starts reading frame 2; the harness's destructor must join it (ASan: no leak)
}

TEST(ExrLoaderPrefetch, DescribeDocumentsTheMemoryCost) {
    auto d = ExrLoader::describe();
    const auto* p = d.findParam("prefetch");
    ASSERT_NE(p, nullptr);
    EXPECT_NE(p->description.find("MB"), std::string::npos);
}

TEST(ExrLoaderPrefetch, FrameSizeChangingMidSequenceMatchesUnprefetched) {
    // Frames 2 and 4 are not the first frame's size: frame errors, with or without the frame
    // read ahead, and the frames around them the same.
    TempDir tmp("prefetch_size");
    const int sizes[][2] = {{32, 24}, {48, 40}, {32, 24}, {16, 16}, {32, 24}};
    for (int f = 1; f <= 5; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "f.%04d.exr", f);
        const int w = sizes[f - 1][0], h = sizes[f - 1][1];
        writeExr(tmp.path / name, box(0, 0, w - 1, h - 1), noise(w, h, uint32_t(f)));
    }
    const std::string pattern = (tmp.path / "f.####.exr").string();
    Frames off = runFrames(pattern, 1, 5, false), on = runFrames(pattern, 1, 5, true);
    for (size_t i = 0; i < 5; ++i) {
        const bool odd = i == 1 || i == 3;
        EXPECT_EQ(on.errors[i], off.errors[i]) << "frame " << i + 1;
        if (odd)
            EXPECT_NE(on.errors[i].find("the first frame"), std::string::npos) << on.errors[i];
        else
            EXPECT_EQ(on.errors[i], "");
        EXPECT_EQ(on.planes[i].size(), odd ? 0 : size_t(sizes[i][0] * sizes[i][1] * 3));
        EXPECT_TRUE(sameBits(off.planes[i], on.planes[i])) << "frame " << i + 1;
    }
}
