#include <gtest/gtest.h>

#include "../SvgfTestImages.h"
#include "TemporalAccumulationPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {
struct History {
    Image color, moments, length;
};

/// One frame with a static camera: last frame's outputs are this frame's reprojected history.
PassHarness step(const Image& cur, const History* hist, std::map<std::string, ParamValue> p = {},
                 int threads = 1) {
    auto h = PassHarness::make<TemporalAccumulationPass>(cur.extent(), p, threads);
    h.bind("color", cur);
    if (hist) {
        h.bind("prevColor", hist->color);
        h.bind("prevMoments", hist->moments);
        h.bind("prevHistoryLength", hist->length);
    }
    h.run();
    return h;
}
History keep(const PassHarness& h) {
    return {clone(h.out("color")), clone(h.out("moments")), clone(h.out("historyLength"))};
}
}  // namespace

TEST(TemporalAccumulation, FirstFrameIsTheInputWithLengthOne) {
    Image cur = grey(4, 3, [](int x, int y) { return 0.5f + 0.1f * float(x + y); });
    auto h = step(cur, nullptr);
    EXPECT_FLOAT_EQ(h.out("color").at(0, 2, 1), 0.8f);
    EXPECT_FLOAT_EQ(h.out("historyLength").at(0, 2, 1), 1.f);
    EXPECT_FLOAT_EQ(h.out("moments").at(0, 2, 1), 0.8f);  // grey: luminance = value
    EXPECT_NEAR(h.out("variance").at(0, 2, 1), 0.f, 1e-7f);
}

TEST(TemporalAccumulation, BlendUsesMaxOfAlphaAndInverseLength) {
    Image zero = constant(3, 3, Format::Float3, 0.f), one = constant(3, 3, Format::Float3, 1.f);
    History hist{clone(zero), constant(3, 3, Format::Float2, 0.f),
                 constant(3, 3, Format::Float, 9.f)};
    auto h = step(one, &hist);  // length 10: alpha = max(0.2, 0.1) = 0.2
    EXPECT_FLOAT_EQ(h.out("historyLength").at(0, 1, 1), 10.f);
    EXPECT_FLOAT_EQ(h.out("color").at(1, 1, 1), 0.2f);
    EXPECT_FLOAT_EQ(h.out("moments").at(0, 1, 1), 0.2f);
    EXPECT_FLOAT_EQ(h.out("moments").at(1, 1, 1), 0.2f);
    EXPECT_FLOAT_EQ(h.out("variance").at(0, 1, 1), 0.2f - 0.04f);
    hist.length.fill(1.f);  // length 2: alpha = 0.5
    auto h2 = step(one, &hist);
    EXPECT_FLOAT_EQ(h2.out("color").at(1, 1, 1), 0.5f);
}

TEST(TemporalAccumulation, HistoryLengthSaturatesAtCap) {
    Image cur = constant(5, 4, Format::Float3, 0.7f);
    std::map<std::string, ParamValue> p{{"maxHistoryLength", 6.0}};
    auto h = step(cur, nullptr, p);
    History hist = keep(h);
    for (int f = 1; f < 12; ++f) {
        auto hf = step(cur, &hist, p);
        EXPECT_FLOAT_EQ(hf.out("historyLength").at(0, 2, 2), std::min(6.f, float(f + 1)));
        hist = keep(hf);
    }
    // Constant input stays constant through accumulation.
    EXPECT_NEAR(hist.color.at(0, 3, 1), 0.7f, 1e-6f);
}

TEST(TemporalAccumulation, FireflyIsClampedBeforeEnteringHistory) {
    Image cur = constant(5, 5, Format::Float3, 1.f);
    for (int c = 0; c < 3; ++c) cur.at(c, 2, 2) = 1e6f;
    auto clamped = step(cur, nullptr);
    // Neighbours are all 1 (stddev 0): the firefly is scaled down to luminance 1; its moments
    // take at most twice that bound.
    EXPECT_NEAR(clamped.out("color").at(0, 2, 2), 1.f, 1e-5f);
    EXPECT_NEAR(clamped.out("moments").at(0, 2, 2), 2.f, 1e-5f);
    EXPECT_NEAR(clamped.out("moments").at(1, 2, 2), 4.f, 1e-4f);
    auto off = step(cur, nullptr, {{"fireflySigma", 0.0}});
    EXPECT_FLOAT_EQ(off.out("color").at(0, 2, 2), 1e6f);
    // A bright sample consistent with its own (bright, noisy) history is kept.
    History hist{constant(5, 5, Format::Float3, 1.f), constant(5, 5, Format::Float2, 0.f),
                 constant(5, 5, Format::Float, 8.f)};
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 5; ++x) {
            hist.moments.at(0, x, y) = 2.f;    // mean 2
            hist.moments.at(1, x, y) = 104.f;  // stddev 10: bound 2 + 3 * 10 = 32
        }
    Image bright = constant(5, 5, Format::Float3, 1.f);
    for (int c = 0; c < 3; ++c) bright.at(c, 2, 2) = 20.f;
    auto kept = step(bright, &hist);
    EXPECT_NEAR(kept.out("color").at(0, 2, 2), 1.f + 0.2f * (20.f - 1.f), 1e-5f);
}

// The clamp's k is over the weight the sample enters the colour with: without a history a
// sample 8 sigma above its neighbours is clamped to mean + 3 sigma; with a long history (weight
// alpha 0.2, k' = 15) it is kept, its effect on the accumulated colour already 5x smaller.
TEST(TemporalAccumulation, FireflyBoundWidensWithTheHistory) {
    Image cur = grey(3, 3, [](int x, int y) { return (x + y) % 2 ? 0.5f : 1.5f; });  // sigma 0.5
    for (int c = 0; c < 3; ++c) cur.at(c, 1, 1) = 5.f;  // mean 1 + 8 sigma
    auto first = step(cur, nullptr);
    EXPECT_NEAR(first.out("color").at(0, 1, 1), 2.5f, 1e-5f);
    History hist{constant(3, 3, Format::Float3, 1.f), constant(3, 3, Format::Float2, 1.f),
                 constant(3, 3, Format::Float, 8.f)};  // mean 1, no variance of its own
    auto later = step(cur, &hist);
    EXPECT_NEAR(later.out("color").at(0, 1, 1), 1.f + 0.2f * (5.f - 1.f), 1e-5f);
}

// A noise-free highlight under a still camera (a glint, a sun reflection at 1 spp) is bright
// against its neighbours every frame. Its first frames are clamped as a firefly would be, but its
// history bound rises until it passes; with the moments held at the bound it stayed at the
// neighbours' level for good (a dim street's still-camera glossy region: 0.644 of the input's MSE
// against 0.575).
TEST(TemporalAccumulation, RecurringBrightSampleRisesThroughTheClamp) {
    Image cur = constant(5, 5, Format::Float3, 1.f);
    for (int c = 0; c < 3; ++c) cur.at(c, 2, 2) = 20.f;
    auto first = step(cur, nullptr);
    EXPECT_NEAR(first.out("color").at(0, 2, 2), 1.f, 1e-5f);
    History hist = keep(first);
    for (int f = 1; f < 24; ++f) {
        auto h = step(cur, &hist);
        hist = keep(h);
    }
    EXPECT_GT(hist.color.at(0, 2, 2), 19.f);
    EXPECT_NEAR(hist.color.at(0, 1, 2), 1.f, 1e-5f);  // the neighbours are untouched
}

// A block of hugely negative radiance (-1e10 passes the loader) is as damaged as its
// neighbours, so they cannot bound it; its valid history can. It entered unclamped and held the
// history negative for frames. Without a history it is left as it is.
TEST(TemporalAccumulation, NegativeBlockIsHeldToItsHistorysLowerBound) {
    Image cur = constant(5, 5, Format::Float3, -1e10f);
    History hist{constant(5, 5, Format::Float3, 0.5f), constant(5, 5, Format::Float2, 0.5f),
                 constant(5, 5, Format::Float, 8.f)};
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 5; ++x) hist.moments.at(1, x, y) = 0.26f;  // stddev 0.1
    auto h = step(cur, &hist);
    // k' = 3 / 0.2 = 15: mean 0.5 - 15 * 0.1 = -1; the colour is blended towards it at 0.2.
    EXPECT_NEAR(h.out("color").at(0, 2, 2), 0.5f + 0.2f * (-1.f - 0.5f), 1e-4f);
    EXPECT_NEAR(h.out("moments").at(0, 2, 2), 0.5f + 0.2f * (-1.f - 0.5f), 1e-4f);
    auto none = step(cur, nullptr);
    EXPECT_FLOAT_EQ(none.out("color").at(0, 2, 2), -1e10f);
    auto off = step(cur, &hist, {{"fireflySigma", 0.0}});
    EXPECT_LT(off.out("color").at(0, 2, 2), -1e9f);
}

TEST(TemporalAccumulation, NonFiniteInputsGiveFiniteOutputs) {
    Image cur = constant(4, 4, Format::Float3, 1.f);
    cur.at(0, 1, 1) = NAN;
    cur.at(1, 2, 2) = INFINITY;
    History hist{constant(4, 4, Format::Float3, 1.f), constant(4, 4, Format::Float2, 1.f),
                 constant(4, 4, Format::Float, 3.f)};
    hist.color.at(2, 0, 0) = NAN;
    hist.moments.at(1, 3, 3) = INFINITY;
    hist.length.at(0, 0, 3) = NAN;
    auto h = step(cur, &hist);
    for (const char* o : {"color", "moments", "historyLength", "variance"})
        EXPECT_TRUE(allFinite(h.out(o))) << o;
}

TEST(TemporalAccumulation, IdenticalWithOneAndTwoThreads) {
    const int w = 40, h = 130;
    Image cur = grey(
        w, h, [](int x, int y) { return hash01(x, y) * (hash01(x, y, 3) > 0.97f ? 100.f : 1.f); });
    History hist{grey(w, h, [](int x, int y) { return hash01(x, y, 1); }),
                 Image(w, h, Format::Float2),
                 scalar(w, h, [](int x, int y) { return std::floor(hash01(x, y, 2) * 5.f); })};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            hist.moments.at(0, x, y) = 0.5f;
            hist.moments.at(1, x, y) = 0.4f;
        }
    auto a = step(cur, &hist, {}, 1);
    auto b = step(cur, &hist, {}, 2);
    for (const char* o : {"color", "moments", "historyLength", "variance"})
        EXPECT_TRUE(identical(a.out(o), b.out(o))) << o;
}
