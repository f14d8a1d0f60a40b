#include <gtest/gtest.h>

#include <deque>

#include "../SameBits.h"
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
        EXPECT_TRUE(sameBits(a.out(o), b.out(o))) << o;
}

// ---- The firefly clamp's excess spread over the same surface (FireflySpread.h) ----
namespace {
/// One frame with a valid history and a G-buffer: a plane facing the camera at depth 2 (ids
/// from `id`), optionally with NaN/Inf planted in depth and normal.
PassHarness spreadStep(
    const Image& cur, const History& hist, std::map<std::string, ParamValue> p, int threads = 1,
    const std::function<int(int, int)>& id = [](int, int) { return 1; },
    bool damagedGbuffer = false) {
    const int w = cur.extent().width, h = cur.extent().height;
    auto hs = PassHarness::make<TemporalAccumulationPass>(cur.extent(), p, threads);
    // The G-buffer outlives the harness that reads it: kept for the test program's life (a
    // harness binds views, and the caller reads its outputs after this returns).
    static std::deque<Image> kept;
    Image& depth = kept.emplace_back(scalar(w, h, [](int, int) { return 2.f; }));
    Image& normal = kept.emplace_back(normals(w, h, 0.f, 0.f, 1.f));
    Image& object = kept.emplace_back(ids(w, h, id));
    if (damagedGbuffer) {
        depth.at(0, 1, 1) = NAN;
        depth.at(0, w - 2, h - 2) = INFINITY;
        normal.at(0, 2, 1) = NAN;
        normal.at(2, w / 2, h / 2) = -INFINITY;
    }
    hs.bind("color", cur);
    hs.bind("prevColor", hist.color);
    hs.bind("prevMoments", hist.moments);
    hs.bind("prevHistoryLength", hist.length);
    hs.bind("depth", depth);
    hs.bind("normal", normal);
    hs.bind("objectId", object);
    hs.run();
    return hs;
}
/// A dark plane with a long, settled history: a sample of 1000 at (x, y) is a firefly.
History darkHistory(int w, int h) {
    History hist{constant(w, h, Format::Float3, 0.01f), constant(w, h, Format::Float2, 0.f),
                 constant(w, h, Format::Float, 8.f)};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            hist.moments.at(0, x, y) = 0.01f;
            hist.moments.at(1, x, y) = 0.0001f;
        }
    return hist;
}
double sum(const Image& im, int c) {
    double s = 0.0;
    for (int y = 0; y < im.extent().height; ++y)
        for (int x = 0; x < im.extent().width; ++x) s += im.at(c, x, y);
    return s;
}
}  // namespace

// A lamp the 1-spp frames reach only by rare samples: the clamp keeps the firefly out of its
// pixel, and with fireflySpread its energy lands on the surface around it instead of being
// lost, so the frame's total is what it would be without the clamp.
TEST(TemporalAccumulation, FireflySpreadKeepsTheClampedEnergy) {
    const int w = 15, h = 15;
    Image cur = constant(w, h, Format::Float3, 0.01f);
    for (int c = 0; c < 3; ++c) cur.at(c, 7, 7) = 0.2f;  // 20x its bound (0.01), under the hold
    const History hist = darkHistory(w, h);
    auto unclamped = spreadStep(cur, hist, {{"fireflySigma", 0.0}});
    auto dropped = spreadStep(cur, hist, {{"fireflySpread", 0}});
    // fireflyFullShare 0.01: all of it is kept (it is 7% of its window's light)
    auto spread = spreadStep(cur, hist, {{"fireflySpread", 3}, {"fireflyFullShare", 0.01}});
    const double all = sum(unclamped.out("color"), 0);
    EXPECT_GT(all - sum(dropped.out("color"), 0), 0.035);  // SVGF's clamp drops 0.2 * 0.19
    EXPECT_NEAR(sum(spread.out("color"), 0), all, 1e-4 * all);
    // Spread over the 7x7 window, fading with distance (a Gaussian of sigma 1.5 px), not left in
    // the firefly's own pixel.
    auto added = [&](int x, int y) {
        return spread.out("color").at(0, x, y) - dropped.out("color").at(0, x, y);
    };
    EXPECT_GT(added(7, 7), added(6, 7));
    EXPECT_NEAR(added(6, 7) / added(7, 7), std::exp(-1.f / 4.5f), 1e-3f);
    EXPECT_NEAR(added(4, 10) / added(7, 7), std::exp(-18.f / 4.5f), 1e-3f);
    EXPECT_GT(added(4, 10), 0.f);
    EXPECT_FLOAT_EQ(spread.out("color").at(0, 3, 7), dropped.out("color").at(0, 3, 7));  // outside
}

// The excess stays on its object: a firefly beside another object's edge lights nothing of it.
TEST(TemporalAccumulation, FireflySpreadStaysOnItsObject) {
    const int w = 15, h = 9;
    Image cur = constant(w, h, Format::Float3, 0.01f);
    for (int c = 0; c < 3; ++c) cur.at(c, 6, 4) = 0.5f;
    const History hist = darkHistory(w, h);
    auto split = [](int x, int) { return x < 7 ? 1 : 2; };
    auto dropped = spreadStep(cur, hist, {{"fireflySpread", 0}}, 1, split);
    auto spread = spreadStep(cur, hist, {{"fireflySpread", 4}}, 1, split);
    for (int y = 0; y < h; ++y)
        for (int x = 7; x < w; ++x)
            EXPECT_FLOAT_EQ(spread.out("color").at(0, x, y), dropped.out("color").at(0, x, y));
    EXPECT_GT(spread.out("color").at(0, 3, 4), dropped.out("color").at(0, 3, 4) + 1e-3f);
}

// A sample of 1e10 is no light to keep: each pixel receives at most twice the sample's clamp
// bound (0.01), as it enters the accumulation (alpha 0.2).
TEST(TemporalAccumulation, FireflySpreadGivesEachPixelAtMostTwoBounds) {
    const int w = 15, h = 15;
    Image cur = constant(w, h, Format::Float3, 0.25f);  // 0.25: its squares are exact
    for (int c = 0; c < 3; ++c) cur.at(c, 7, 7) = 1e10f;
    const History hist{constant(w, h, Format::Float3, 0.25f), constant(w, h, Format::Float2, 0.25f),
                       constant(w, h, Format::Float, 8.f)};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) hist.moments.at(1, x, y) = 0.0625f;  // no variance
    auto dropped = spreadStep(cur, hist, {{"fireflySpread", 0}});
    auto spread = spreadStep(cur, hist, {{"fireflySpread", 3}});
    const float most = 2.f * 0.25f * 0.2f;  // two bounds, entering at alpha 0.2, at the centre
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float added = spread.out("color").at(0, x, y) - dropped.out("color").at(0, x, y);
            EXPECT_LE(added, most * 1.0001f) << x << "," << y;
            if (std::abs(x - 7) <= 3 && std::abs(y - 7) <= 3) {  // the falloff times the hold
                const float d2 = float((x - 7) * (x - 7) + (y - 7) * (y - 7));
                EXPECT_NEAR(added, most * std::exp(-d2 / 4.5f), 1e-4f * most) << x << "," << y;
            }
        }
}

// A noise tail (an excess that is a small share of the light around it) is dropped as SVGF
// drops it; only the share of fireflyFullShare is kept: with the window's clamped share s, the
// kept part is min(1, s / fireflyFullShare) of the excess.
TEST(TemporalAccumulation, FireflySpreadKeepsTheShareOfTheLightItCarries) {
    const int w = 15, h = 15;
    Image cur = constant(w, h, Format::Float3, 1.f);
    for (int c = 0; c < 3; ++c)
        cur.at(c, 7, 7) = 250.f;  // its centre's share under two bounds (0.4)
    const History hist{constant(w, h, Format::Float3, 1.f), constant(w, h, Format::Float2, 1.f),
                       constant(w, h, Format::Float, 8.f)};  // mean 1, no variance
    auto unclamped = spreadStep(cur, hist, {{"fireflySigma", 0.0}});
    auto dropped = spreadStep(cur, hist, {{"fireflySpread", 0}});
    const double excess = sum(unclamped.out("color"), 0) - sum(dropped.out("color"), 0);
    // The whole frame is the window at radius 7: its clamped share is excess / all (about 0.18).
    const double share = excess / sum(unclamped.out("color"), 0);
    ASSERT_LT(share, 0.5);
    auto half = spreadStep(cur, hist, {{"fireflySpread", 7}, {"fireflyFullShare", 2.0 * share}});
    EXPECT_NEAR(sum(half.out("color"), 0) - sum(dropped.out("color"), 0), 0.5 * excess,
                1e-3 * excess);
}

// A sample without a history is its pixel's whole colour: the clamp's excess is dropped there
// (spreading it brought back the noise the clamp removes on a first frame or a disocclusion).
TEST(TemporalAccumulation, FireflySpreadNeedsAHistory) {
    const int w = 9, h = 9;
    Image cur = constant(w, h, Format::Float3, 0.01f);
    for (int c = 0; c < 3; ++c) cur.at(c, 4, 4) = 1000.f;
    History none = darkHistory(w, h);
    none.length.fill(0.f);
    auto dropped = spreadStep(cur, none, {{"fireflySpread", 0}});
    auto spread = spreadStep(cur, none, {{"fireflySpread", 3}});
    EXPECT_TRUE(sameBits(spread.out("color"), dropped.out("color")));
}

TEST(TemporalAccumulation, FireflySpreadIsIdenticalWithOneAndTwoThreadsAndFiniteOnDamage) {
    const int w = 40, h = 130;
    Image cur = grey(
        w, h, [](int x, int y) { return hash01(x, y) * (hash01(x, y, 3) > 0.97f ? 100.f : 1.f); });
    History hist = darkHistory(w, h);
    auto stripes = [](int x, int y) { return (x / 7 + y / 11) % 3; };
    auto a = spreadStep(cur, hist, {{"fireflySpread", 9}}, 1, stripes, true);
    auto b = spreadStep(cur, hist, {{"fireflySpread", 9}}, 2, stripes, true);
    EXPECT_TRUE(sameBits(a.out("color"), b.out("color")));
    EXPECT_TRUE(allFinite(a.out("color")));
    auto dropped = spreadStep(cur, hist, {{"fireflySpread", 0}}, 1, stripes, true);
    EXPECT_GT(sum(a.out("color"), 1), sum(dropped.out("color"), 1));
}
