// TAA: fixed point on constant input, convergence on a static input, reset on disocclusion,
// rejection of outlier history, noise reduction, stiff inputs, thread-count independence.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <random>

#include "TaaPass.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using namespace kestrel::passes;
using kestrel::testing::PassHarness;

namespace {

Image copyOf(const Image& src) {
    Image dst(src.extent(), src.format());
    for (int c = 0; c < channelCount(src.format()); ++c)
        std::copy_n(src.channel(c), src.extent().pixels(), dst.channel(c));
    return dst;
}

float maxAbsDiff(const Image& a, const Image& b) {
    float m = 0;
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < a.extent().pixels(); ++i)
            m = std::max(m, std::fabs(a.channel(c)[i] - b.channel(c)[i]));
    return m;
}

double meanAbsDiff(const Image& a, const Image& b) {
    double s = 0;
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < a.extent().pixels(); ++i)
            s += std::fabs(a.channel(c)[i] - b.channel(c)[i]);
    return s / (3.0 * double(a.extent().pixels()));
}

/// A static test image with smooth shading, hard edges and a one-pixel highlight.
Image texture(int w, int h) {
    Image img(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float checker = ((x / 4 + y / 4) % 2) ? 0.8f : 0.2f;
            img.at(0, x, y) = checker * (0.5f + 0.5f * float(x) / float(w));
            img.at(1, x, y) = checker;
            img.at(2, x, y) = 0.3f + 0.4f * float(y) / float(h);
        }
    for (int c = 0; c < 3; ++c) img.at(c, w / 2, h / 2) = 4.f;
    return img;
}

}  // namespace

TEST(Taa, ConstantStaysConstant) {
    Image cur(12, 9, Format::Float3);
    for (int c = 0; c < 3; ++c) std::fill_n(cur.channel(c), cur.extent().pixels(), 0.2f + 0.3f * c);
    auto h = PassHarness::make<TaaPass>(cur.extent());
    h.bind("color", cur);
    h.bind("history", cur);
    h.run();
    EXPECT_LT(maxAbsDiff(h.out("color"), cur), 1e-6f);  // YCoCg round trip only
}

/// Feeds TAA its own output for `frames` frames on a static input, history starting black;
/// returns the max error after each frame and checks it never grows.
static std::vector<float> convergence(const Image& cur, int frames, bool antiFlicker) {
    Image hist(cur.extent(), Format::Float3);
    auto h = PassHarness::make<TaaPass>(cur.extent(), {{"antiFlicker", antiFlicker}});
    h.bind("color", cur);
    std::vector<float> errs;
    for (int frame = 1; frame <= frames; ++frame) {
        h.bind("history", hist);
        h.run();
        errs.push_back(maxAbsDiff(h.out("color"), cur));
        if (errs.size() > 1) {
            EXPECT_LE(errs.back(), errs[errs.size() - 2] * 1.0001f + 1e-6f) << frame;
        }
        hist = copyOf(h.out("color"));
    }
    return errs;
}

TEST(Taa, ConvergesOnStaticInput) {
    // Max error, measured (the worst pixel is the 4.0 highlight):
    //   plain blend:  3.6 after 1 frame, 0.49 after 20, 8.8e-4 after 80 (decay 0.9 = 1 - alpha);
    //   antiFlicker:  3.9 after 1 frame, 1.6 after 20, 4.4e-3 after 80, 6.4e-5 after 120
    //   (inverse-luminance
    //                 weights give a bright pixel a smaller effective alpha: slower, still exact).
    const Image cur = texture(32, 24);
    std::vector<float> plain = convergence(cur, 80, false);
    EXPECT_LT(plain[19], 0.6f);
    EXPECT_LT(plain[79], 2e-3f);
    std::vector<float> weighted = convergence(cur, 120, true);
    EXPECT_LT(weighted[19], 2.f);
    EXPECT_LT(weighted[79], 1e-2f);
    EXPECT_LT(weighted[119], 2e-3f);
    std::printf("TAA convergence: plain %.3g %.3g %.3g, antiFlicker %.3g %.3g %.3g %.3g\n",
                plain[0], plain[19], plain[79], weighted[0], weighted[19], weighted[79],
                weighted[119]);
}

TEST(Taa, ResetsOnDisocclusion) {
    const Image cur = texture(16, 16);
    Image hist(cur.extent(), Format::Float3), len(cur.extent(), Format::Float);
    hist.fill(0.5f);
    len.fill(4.f);
    for (int y = 4; y < 10; ++y)
        for (int x = 3; x < 8; ++x) len.at(0, x, y) = 0.f;
    auto h = PassHarness::make<TaaPass>(cur.extent());
    h.bind("color", cur);
    h.bind("history", hist);
    h.bind("historyLength", len);
    h.run();
    int used = 0;
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            for (int c = 0; c < 3; ++c) {
                const float o = h.out("color").at(c, x, y), in = cur.at(c, x, y);
                if (len.at(0, x, y) == 0.f)
                    ASSERT_EQ(o, in) << x << "," << y;  // exactly the current colour
                else
                    used += std::fabs(o - in) > 1e-4f;
            }
    EXPECT_GT(used, 300);  // elsewhere the history does contribute
}

TEST(Taa, ClipRejectsOutlierHistory) {
    // Grey neighbourhood with values in [0, 1]: the YCoCg box is [mu - sigma, mu + sigma] in Y
    // (sigma <= 0.5) and a point in chroma, so an outlier history of 100 is cut to <= 1.5 and
    // the output to <= 0.1 * 1 + 0.9 * 1.5 = 1.45. With a 100-sigma box the output is 29.
    Image cur(7, 7, Format::Float3), hist(7, 7, Format::Float3);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    for (size_t i = 0; i < 49; ++i) {
        const float v = u(rng);
        for (int c = 0; c < 3; ++c) cur.channel(c)[i] = v, hist.channel(c)[i] = v;
    }
    for (int c = 0; c < 3; ++c) hist.at(c, 3, 3) = 100.f;
    for (const char* mode : {"clip", "clamp"}) {
        auto h = PassHarness::make<TaaPass>({7, 7}, {{"mode", std::string(mode)}});
        h.bind("color", cur);
        h.bind("history", hist);
        h.run();
        for (int c = 0; c < 3; ++c) EXPECT_LE(h.out("color").at(c, 3, 3), 1.45f) << mode;
    }
    auto wide = PassHarness::make<TaaPass>({7, 7}, {{"gamma", 100.0}, {"antiFlicker", false}});
    wide.bind("color", cur);
    wide.bind("history", hist);
    wide.run();
    EXPECT_GT(wide.out("color").at(0, 3, 3), 20.f);  // the test can fail: the box does the work
}

TEST(Taa, ReducesNoiseOnStaticInput) {
    // Static texture plus fresh uniform noise (+-0.1) every frame, 40 frames. Measured mean
    // absolute error against the clean texture: input 0.050, output 0.0145 (gamma 1, 3x3 box).
    const Image ref = texture(40, 30);
    std::mt19937 rng(2);
    std::uniform_real_distribution<float> noise(-0.1f, 0.1f);
    auto h = PassHarness::make<TaaPass>(ref.extent());
    Image hist(ref.extent(), Format::Float3);
    double inErr = 0, outErr = 0;
    for (int frame = 0; frame < 40; ++frame) {
        Image cur = copyOf(ref);
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < ref.extent().pixels(); ++i) cur.channel(c)[i] += noise(rng);
        h.bind("color", cur);
        if (frame > 0) h.bind("history", hist);
        h.run();
        hist = copyOf(h.out("color"));
        if (frame >= 20) {
            inErr += meanAbsDiff(cur, ref);
            outErr += meanAbsDiff(h.out("color"), ref);
        }
    }
    std::printf("TAA noise: input %.4f output %.4f\n", inErr / 20, outErr / 20);
    EXPECT_LT(outErr, 0.5 * inErr);
}

TEST(Taa, StiffInputsGiveFiniteOutput) {
    const float inf = std::numeric_limits<float>::infinity();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    Image cur = texture(10, 10), hist = texture(10, 10);
    cur.at(0, 1, 1) = nan;
    cur.at(1, 4, 4) = inf;
    cur.at(2, 5, 4) = -inf;
    cur.at(0, 8, 8) = 1e30f;
    hist.at(1, 2, 2) = nan;
    hist.at(0, 6, 2) = inf;
    hist.at(2, 7, 7) = -1e30f;
    auto h = PassHarness::make<TaaPass>({10, 10});
    h.bind("color", cur);
    h.bind("history", hist);
    h.run();
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < 100; ++i)
            ASSERT_TRUE(std::isfinite(h.out("color").channel(c)[i])) << i;
    // A NaN history pixel is dropped like a disocclusion.
    for (int c = 0; c < 3; ++c) EXPECT_EQ(h.out("color").at(c, 2, 2), cur.at(c, 2, 2));
}

TEST(Taa, OneAndTwoThreadsIdentical) {
    const Extent e{97, 71};
    Image cur(e, Format::Float3), hist(e, Format::Float3), len(e, Format::Float);
    std::mt19937 rng(4);
    std::uniform_real_distribution<float> u(0.f, 3.f);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < e.pixels(); ++i)
            cur.channel(c)[i] = u(rng), hist.channel(c)[i] = u(rng);
    for (size_t i = 0; i < e.pixels(); ++i) len.channel(0)[i] = float(i % 3);
    auto h1 = PassHarness::make<TaaPass>(e, {}, 1);
    auto h2 = PassHarness::make<TaaPass>(e, {}, 2);
    for (auto* h : {&h1, &h2}) {
        h->bind("color", cur);
        h->bind("history", hist);
        h->bind("historyLength", len);
        h->run();
    }
    EXPECT_EQ(maxAbsDiff(h1.out("color"), h2.out("color")), 0.f);
}

// History resampled between pixel centres (Reprojection's resampleBlur) is weighted down: at
// blur 1 with blurAlpha 1 the output is the current colour, at blur 0 the pass is bit for bit
// the one without the input, and in between the history's share lies between the two.
TEST(Taa, BlurredHistoryIsWeightedDown) {
    const Image cur = texture(16, 16);
    Image hist(cur.extent(), Format::Float3), blur(cur.extent(), Format::Float);
    hist.fill(0.45f);
    auto runWith = [&](const Image* b) {
        auto h = PassHarness::make<TaaPass>(cur.extent(), {{"gamma", 100.0}});
        h.bind("color", cur);
        h.bind("history", hist);
        if (b) h.bind("resampleBlur", *b);
        h.run();
        return copyOf(h.out("color"));
    };
    const Image without = runWith(nullptr);
    blur.fill(0.f);
    EXPECT_EQ(maxAbsDiff(runWith(&blur), without), 0.f);
    blur.fill(1.f);
    EXPECT_LT(maxAbsDiff(runWith(&blur), cur), 1e-6f);
    blur.fill(0.5f);
    const double half = meanAbsDiff(runWith(&blur), cur), full = meanAbsDiff(without, cur);
    EXPECT_GT(half, 0.05 * full);
    EXPECT_LT(half, 0.7 * full);
}

// warmUp: historyLength is TAA's own age (its historyLength output fed back). A history of one
// frame keeps a third of its weight (current 2 / (1 + 2)), not 1 - alpha = 0.9; an old history
// (age 18 and more) the usual 0.9. The age output counts the frames in the result.
TEST(Taa, WarmUpWeightsYoungHistoriesDown) {
    constexpr int W = 24, H = 16;
    Image cur(W, H, Format::Float3), hist(W, H, Format::Float3), len(W, H, Format::Float);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.2f, 0.8f);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < cur.extent().pixels(); ++i) {
            cur.channel(c)[i] = u(rng);  // every 3x3 box is wide: the history is not clipped
            hist.channel(c)[i] = cur.channel(c)[i] + 0.01f;
        }
    auto historyShare = [&](bool warmUp, float age, float* ageOut) {
        len.fill(age);
        auto h =
            PassHarness::make<TaaPass>(cur.extent(), {{"warmUp", warmUp}, {"antiFlicker", false}});
        h.bind("color", cur);
        h.bind("history", hist);
        h.bind("historyLength", len);
        h.run();
        *ageOut = h.out("historyLength").at(0, 5, 5);
        return (h.out("color").at(1, 5, 5) - cur.at(1, 5, 5)) / 0.01f;
    };
    float age = 0;
    EXPECT_NEAR(historyShare(false, 1.f, &age), 0.9f, 1e-3f);
    EXPECT_EQ(age, 2.f);
    EXPECT_NEAR(historyShare(true, 1.f, &age), 1.f / 3.f, 1e-3f);
    EXPECT_NEAR(historyShare(true, 3.f, &age), 0.6f, 1e-3f);  // current 2 / 5
    EXPECT_EQ(age, 4.f);
    EXPECT_NEAR(historyShare(true, 30.f, &age), 0.9f, 1e-3f);
    EXPECT_NEAR(historyShare(true, 1000.f, &age), 0.9f, 1e-3f);
    EXPECT_EQ(age, 255.f);
}

namespace {

/// The compile-time view of one pass: which inputs are bound and which scene facts sources
/// stated; what it forwards and ignores.
struct StubResolve : ResolveContext {
    std::vector<std::string> bound, ignored, forwarded;
    std::map<std::string, std::string> facts;
    bool isBound(std::string_view in) const override {
        return std::find(bound.begin(), bound.end(), in) != bound.end();
    }
    void forward(std::string_view out, std::string_view in) override {
        forwarded.push_back(std::string(out) + "<-" + std::string(in));
    }
    void setAbsent(std::string_view, std::string) override {}
    void ignoreInput(std::string_view in, std::string) override { ignored.emplace_back(in); }
    void note(std::string) override {}
    std::optional<std::string> fact(std::string_view key) const override {
        const auto it = facts.find(std::string(key));
        return it == facts.end() ? std::nullopt : std::optional<std::string>(it->second);
    }
    int64_t firstFrame() const override { return 1; }
    std::string_view passName() const override { return "taa"; }
};

/// `antiAliased`: the source's fact ("" when no source states it).
StubResolve resolveTaa(bool onlyAntiAliased, const std::string& antiAliased, bool history = true) {
    auto h = PassHarness::make<TaaPass>({4, 4}, {{"onlyAntiAliased", onlyAntiAliased}});
    StubResolve rc;
    rc.bound = {"color", "historyLength", "resampleBlur"};
    if (history) rc.bound.push_back("history");
    if (!antiAliased.empty()) rc.facts["antiAliased"] = antiAliased;
    h.pass().resolve(rc);
    return rc;
}

}  // namespace

// onlyAntiAliased leaves TAA out (colour forwarded) unless the source states that the render is
// anti-aliased (the loader's scene fact antiAliased); no image is read for it.
TEST(Taa, OnlyAntiAliasedLeavesThePassOutOnPointSampledRenders) {
    const std::vector<std::string> passThrough{"color<-color"};
    EXPECT_EQ(resolveTaa(true, "false").forwarded, passThrough);
    EXPECT_EQ(resolveTaa(true, "").forwarded, passThrough);  // no source says so
    const StubResolve aa = resolveTaa(true, "true");
    EXPECT_TRUE(aa.forwarded.empty());
    EXPECT_TRUE(aa.ignored.empty());
    EXPECT_TRUE(resolveTaa(false, "false").forwarded.empty());  // runs unless asked otherwise
    // No history bound: the colour passes through.
    const StubResolve noHistory = resolveTaa(true, "true", false);
    EXPECT_EQ(noHistory.forwarded, passThrough);
    EXPECT_TRUE(noHistory.ignored.empty());
}
