#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "../SvgfTestImages.h"
#include "AntiLagPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {

constexpr int kW = 40, kH = 24;

/// 1-spp-like colour: mean `mean`, each pixel uniformly within +-50% of it.
Image noisy(float mean, int seed) {
    Image im(kW, kH, Format::Float3);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            for (int c = 0; c < 3; ++c) im.at(c, x, y) = mean * (0.5f + hash01(x, y, seed));
    return im;
}

/// AntiLag's output length for this frame's colour, a history and a uniform history length.
Image gated(const Image& color, const Image& history, float length, int threads = 1,
            const std::map<std::string, ParamValue>& params = {}) {
    const Image len = constant(kW, kH, Format::Float, length);
    auto h = PassHarness::make<AntiLagPass>({kW, kH}, params, threads);
    h.bind("color", color);
    h.bind("history", history);
    h.bind("historyLength", len);
    h.run();
    return clone(h.out("historyLength"));
}

}  // namespace

// Unchanged lighting: the current frame's noise around the history's value never shortens it.
TEST(AntiLag, NoisyFrameUnderUnchangedLightKeepsTheHistory) {
    const Image out = gated(noisy(1.f, 3), constant(kW, kH, Format::Float3, 1.f), 10.f);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) ASSERT_EQ(out.at(0, x, y), 10.f) << x << "," << y;
}

// A light switched off (the history is 1, the frame 0.15 with noise): lambda ~0.8, so the
// current frame's weight rises from 1/11 to ~0.8 (A-SVGF's alpha'), a length below 0.3.
TEST(AntiLag, LightSwitchedOffShortensTheHistory) {
    const Image out = gated(noisy(0.15f, 4), constant(kW, kH, Format::Float3, 1.f), 10.f);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            ASSERT_LT(out.at(0, x, y), 0.3f) << x << "," << y;
            ASSERT_GE(out.at(0, x, y), 0.f);
        }
}

// And switched on: the same from the other side.
TEST(AntiLag, LightSwitchedOnShortensTheHistory) {
    const Image out = gated(noisy(1.f, 5), constant(kW, kH, Format::Float3, 0.15f), 10.f);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) ASSERT_LT(out.at(0, x, y), 1.f) << x << "," << y;
}

// A change no larger than the noise explains is left alone: sigma is what it is for.
TEST(AntiLag, SigmaSetsTheChangeTheNoiseExplains) {
    const Image color = noisy(1.f, 6), history = constant(kW, kH, Format::Float3, 1.1f);
    const Image strict = gated(color, history, 10.f, 1, {{"sigma", 0.0}});
    const Image tolerant = gated(color, history, 10.f, 1, {{"sigma", 20.0}});
    EXPECT_LT(strict.at(0, kW / 2, kH / 2), 10.f);
    EXPECT_EQ(tolerant.at(0, kW / 2, kH / 2), 10.f);
}

// Only relative differences count: the same lengths at 1000x and 0.001x the light.
TEST(AntiLag, SameResultAtAnyExposure) {
    const Image color = noisy(0.4f, 7), history = noisy(1.f, 8);
    const Image base = gated(color, history, 6.f);
    for (float k : {1e-3f, 1e3f}) {
        Image c = noisy(0.4f * k, 7), h = noisy(k, 8);
        const Image out = gated(c, h, 6.f);
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x)
                ASSERT_NEAR(out.at(0, x, y), base.at(0, x, y), 1e-4f) << k << " " << x << "," << y;
    }
}

// No history stays no history; non-finite inputs give finite lengths no longer than the input.
TEST(AntiLag, MissingHistoryAndNonFiniteInputs) {
    Image color = noisy(1.f, 9), history = noisy(1.f, 10);
    color.at(0, 3, 3) = NAN;
    color.at(1, 5, 5) = INFINITY;
    history.at(2, 7, 7) = -INFINITY;
    Image len = constant(kW, kH, Format::Float, 8.f);
    len.at(0, 1, 1) = 0.f;
    len.at(0, 2, 2) = NAN;
    len.at(0, 9, 9) = INFINITY;
    auto h = PassHarness::make<AntiLagPass>({kW, kH}, {});
    h.bind("color", color);
    h.bind("history", history);
    h.bind("historyLength", len);
    h.run();
    const Image& out = h.out("historyLength");
    EXPECT_EQ(out.at(0, 1, 1), 0.f);
    EXPECT_EQ(out.at(0, 2, 2), 0.f);
    EXPECT_EQ(out.at(0, 9, 9), 0.f);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            ASSERT_TRUE(std::isfinite(out.at(0, x, y)));
            ASSERT_LE(out.at(0, x, y), 8.f);
        }
}

// The result does not depend on how many threads share the bands: 300 rows are five 64-row
// bands (the 24-row images above are one), run by 1 and by 3 threads.
TEST(AntiLag, SameResultOnAnyThreadCount) {
    const int w = 16, h = 300;
    Image color(w, h, Format::Float3), history(w, h, Format::Float3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                color.at(c, x, y) = (y < h / 2 ? 0.3f : 1.f) * (0.5f + hash01(x, y, 11 + c));
                history.at(c, x, y) = 0.5f + hash01(x, y, 20 + c);
            }
    const Image len = constant(w, h, Format::Float, 5.f);
    auto run = [&](int threads) {
        auto hr = PassHarness::make<AntiLagPass>({w, h}, {}, threads);
        hr.bind("color", color);
        hr.bind("history", history);
        hr.bind("historyLength", len);
        hr.run();
        return clone(hr.out("historyLength"));
    };
    const Image one = run(1), three = run(3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) ASSERT_EQ(one.at(0, x, y), three.at(0, x, y)) << x << "," << y;
}
