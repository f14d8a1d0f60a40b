// KeepExact keeps the render's own colour only inside a uniform view through a mirror (every
// pixel of the 3x3 window on the mask, their 1-spp luminances agreeing within `agreement`), and
// the filtered colour everywhere else, non-finite and negative renders included.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "../../ExtremeValues.h"
#include "../SvgfTestImages.h"
#include "KeepExactPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {

constexpr int W = 9, H = 7;

struct Inputs {
    Image filtered = constant(W, H, Format::Float3, 0.25f);
    Image rendered = constant(W, H, Format::Float3, 2.f);
    Image mask = constant(W, H, Format::Float, 1.f);
};

PassHarness run(const Inputs& in) {
    auto h = PassHarness::make<KeepExactPass>({W, H});
    h.bind("color", in.filtered);
    h.bind("rendered", in.rendered);
    h.bind("mask", in.mask);
    h.run();
    return h;
}

bool kept(PassHarness& h, const Inputs& in, int x, int y) {
    for (int c = 0; c < 3; ++c)
        if (h.out("color").at(c, x, y) != in.rendered.at(c, x, y)) return false;
    return true;
}

bool filtered(PassHarness& h, const Inputs& in, int x, int y) {
    for (int c = 0; c < 3; ++c)
        if (h.out("color").at(c, x, y) != in.filtered.at(c, x, y)) return false;
    return true;
}

}  // namespace

// A uniform view (within 1%, inside the default agreement): every pixel with a whole window is
// kept; the image's border, which has none, keeps the filtered colour.
TEST(KeepExact, KeepsAUniformViewThroughAMirror) {
    Inputs in;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int c = 0; c < 3; ++c)
                in.rendered.at(c, x, y) = 2.f * (1.f + 0.001f * float(x + y));
    auto h = run(in);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const bool inside = x > 0 && y > 0 && x < W - 1 && y < H - 1;
            EXPECT_TRUE(inside ? kept(h, in, x, y) : filtered(h, in, x, y)) << x << "," << y;
        }
}

// One pixel 1.5x brighter (noise, or the edge of what the mirror shows) and one off the mask:
// no window holding either is kept; the others still are.
TEST(KeepExact, DisagreeingOrUnmaskedWindowsKeepTheFilteredColour) {
    Inputs in;
    for (int c = 0; c < 3; ++c) in.rendered.at(c, 2, 2) = 3.f;
    in.mask.at(0, 6, 4) = 0.f;
    auto h = run(in);
    for (int y = 1; y < H - 1; ++y)
        for (int x = 1; x < W - 1; ++x) {
            const bool nearBright = std::abs(x - 2) <= 1 && std::abs(y - 2) <= 1;
            const bool nearOff = std::abs(x - 6) <= 1 && std::abs(y - 4) <= 1;
            EXPECT_TRUE(nearBright || nearOff ? filtered(h, in, x, y) : kept(h, in, x, y))
                << x << "," << y;
        }
}

// Off the mask, and in a black view, nothing is kept (a black window would agree with itself).
TEST(KeepExact, NothingKeptOffTheMaskOrInABlackView) {
    for (bool black : {false, true}) {
        Inputs in;
        if (black)
            in.rendered = constant(W, H, Format::Float3, 0.f);
        else
            in.mask = constant(W, H, Format::Float, 0.f);
        auto h = run(in);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) EXPECT_TRUE(filtered(h, in, x, y)) << x << "," << y;
    }
}

// A black view (luminance 0) has no ratio to agree on: filtered. Non-finite, negative and
// absurd renders, and a non-finite mask, keep nothing around them; the output stays finite.
TEST(KeepExact, ExtremeRendersAreNeverKept) {
    for (float v : testvalues::extremeValuesAnd({0.f, -1.f, 1e30f})) {
        Inputs in;
        for (int c = 0; c < 3; ++c) in.rendered.at(c, 4, 3) = v;
        in.mask.at(0, 1, 1) = std::numeric_limits<float>::quiet_NaN();
        auto h = run(in);
        EXPECT_TRUE(allFinite(h.out("color"))) << v;
        const bool agrees = std::isfinite(v) && v >= 2.f / 1.02f && v <= 2.f * 1.02f;
        if (!agrees) {
            EXPECT_TRUE(filtered(h, in, 4, 3)) << v;
        }
        EXPECT_TRUE(filtered(h, in, 1, 1)) << v;
        EXPECT_TRUE(filtered(h, in, 2, 2)) << v;
    }
}

// Without a mask (a render without Cycles' Denoising Normal and Normal) the pass is left out:
// its colour is the filtered one, forwarded at compile time.
TEST(KeepExact, LeftOutWithoutAMask) {
    struct Resolve final : ResolveContext {
        std::string forwarded;
        bool isBound(std::string_view in) const override { return in != "mask"; }
        void forward(std::string_view, std::string_view in) override { forwarded = in; }
        void setAbsent(std::string_view, std::string) override {}
        void note(std::string) override {}
        int64_t firstFrame() const override { return 0; }
        std::string_view passName() const override { return "keepExact"; }
    } rc;
    KeepExactPass pass{kestrel::testing::makeParams(KeepExactPass::describe(), {})};
    pass.resolve(rc);
    EXPECT_EQ(rc.forwarded, "color");
}
