#include <gtest/gtest.h>
#include <kestrel/PixelMath.h>
#include <kestrel/Scratch.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "../FactResolve.h"
#include "../SameBits.h"
#include "../SvgfTestImages.h"
#include "ATrousPass.h"
#include "HwyTargets.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

// The tests that compare the vector kernels with the scalar reference (or with themselves on
// clean and dirty inputs) run once per compiled SIMD target this CPU supports.
class ATrousEveryTarget : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(ATrousEveryTarget);

namespace {

struct Scene {
    Image color, var, depth, normal, id;
    Scene copy() const {
        return {clone(color), clone(var), clone(depth), clone(normal),
                id.width() > 0 ? clone(id) : Image()};
    }
};

PassHarness runATrous(const Scene& s, std::map<std::string, ParamValue> params = {},
                      int threads = 1, bool bindVar = true, bool bindId = true,
                      float depthPrecision = 0.f, int nanIdlePlanes = 0) {
    auto h = PassHarness::make<ATrousPass>(s.color.extent(), params, threads);
    if (nanIdlePlanes > 0) h.lendIdlePlanes(nanIdlePlanes, std::numeric_limits<float>::quiet_NaN());
    if (depthPrecision > 0.f) {  // the loader's fact for depth stored as half
        svgftest::FactResolve facts(kDepthPrecisionFact, std::to_string(depthPrecision));
        h.pass().resolve(facts);
    }
    h.bind("color", s.color);
    if (bindVar)
        h.bind("variance", s.var);
    else
        h.useOutputs({"color"});
    h.bind("depth", s.depth);
    h.bind("normal", s.normal);
    if (bindId && s.id.width() > 0) h.bind("objectId", s.id);
    h.run();
    return h;
}

Scene flatScene(int w, int h, float c, float v) {
    return {grey(w, h, [&](int, int) { return c; }), scalar(w, h, [&](int, int) { return v; }),
            scalar(w, h, [](int, int) { return 3.f; }), normals(w, h, 0, 0, 1),
            ids(w, h, [](int, int) { return 1; })};
}

}  // namespace

TEST(PixelMath, FastExp2AndLog2AreAccurate) {
    double worst = 0;
    for (float x = -126.f; x <= 126.f; x += 0.0137f) {
        const double r = std::fabs(double(px::fastExp2(x)) / std::exp2(double(x)) - 1.0);
        worst = std::max(worst, r);
        ASSERT_LT(r, 3e-7) << x;  // the bound PixelMath.h states
    }
    std::printf("fastExp2: worst relative error %.2g on [-126, 126]\n", worst);
    EXPECT_EQ(px::fastExp2(-127.f), 0.f);
    EXPECT_EQ(px::fastExp2(126.5f), std::exp2(126.f));
    EXPECT_EQ(px::fastExp2(-200.f), 0.f);
    EXPECT_EQ(px::fastExp2(-1e30f), 0.f);
    for (float x = 1e-30f; x < 4.f; x *= 1.37f)
        EXPECT_NEAR(px::fastLog2(x), std::log2(x), 3e-6f + 2e-7f * std::fabs(std::log2(x))) << x;
}

TEST(PixelMath, SanitizeKillsNonFinite) {
    EXPECT_EQ(px::sanitize(NAN), 0.f);
    EXPECT_EQ(px::sanitize(INFINITY), 0.f);
    EXPECT_EQ(px::sanitize(-INFINITY), 0.f);
    EXPECT_EQ(px::sanitize(1e30f), px::kMaxRadiance);
    EXPECT_EQ(px::sanitize(-2.5f), -2.5f);
    EXPECT_EQ(px::sanitizePositive(-1.f), 0.f);
    EXPECT_EQ(px::sanitizeDepth(NAN), kBackgroundDepth);
}

TEST(ATrous, ConstantImageStaysConstant) {
    for (int step : {1, 2, 4, 16, 1024})
        for (Extent e : {Extent{9, 7}, Extent{1, 1}, Extent{1, 6}, Extent{5, 1}}) {
            Scene s = flatScene(e.width, e.height, 0.75f, 0.2f);
            auto h = runATrous(s, {{"step", int64_t(step)}});
            for (int y = 0; y < e.height; ++y)
                for (int x = 0; x < e.width; ++x) {
                    for (int c = 0; c < 3; ++c)
                        ASSERT_NEAR(h.out("color").at(c, x, y), 0.75f, 1e-6f) << step;
                    // Variance of a weighted mean of equal variances shrinks (sum w^2 <= (sum
                    // w)^2).
                    ASSERT_LE(h.out("variance").at(0, x, y), 0.2f + 1e-7f);
                    ASSERT_GT(h.out("variance").at(0, x, y), 0.f);
                }
        }
}

// SVGF eq. 1-5 evaluated independently (double precision, libm exp/pow) at the centre of a 5x5
// image where every tap is inside: planar depth, varying normals, luminance and variance.
TEST(ATrous, MatchesFormulaOnHandComputed5x5) {
    const int n = 5;
    auto lum = [](int x, int y) { return 0.5f + 0.1f * float((x * 7 + y * 3) % 5); };
    auto varf = [](int x, int y) {
        return 0.1f + 0.05f * float(x) + 0.02f * float(y) + 0.01f * float(x * y % 3);
    };
    auto depthf = [](int x, int y) { return 2.f + 0.1f * float(x) + 0.05f * float(y); };
    Scene s{grey(n, n, lum), scalar(n, n, varf), scalar(n, n, depthf), Image(n, n, Format::Float3),
            Image()};
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            double v[3] = {0.05 * (x - 2), 0.03 * (y - 2), 1.0};
            double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            for (int c = 0; c < 3; ++c) s.normal.at(c, x, y) = float(v[c] / len);
        }
    const double sigmaZ = 1, sigmaN = 128, sigmaL = 4;
    auto h = runATrous(s);

    const int px = 2, py = 2;
    const double kh[5] = {1.0 / 16, 1.0 / 4, 3.0 / 8, 1.0 / 4, 1.0 / 16};
    // g3x3 prefiltered variance at p (all 9 taps inside).
    double gVar = 0;
    const double g3[3] = {0.25, 0.5, 0.25};
    for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) gVar += g3[i + 1] * g3[j + 1] * s.var.at(0, px + i, py + j);
    const double gradX = 0.1, gradY = 0.05;  // planar depth
    const double zp = s.depth.at(0, px, py), lp = lum(px, py);
    double sw = 0, sc = 0, sv = 0;
    for (int j = -2; j <= 2; ++j)
        for (int i = -2; i <= 2; ++i) {
            const int qx = px + i, qy = py + j;
            double w = kh[i + 2] * kh[j + 2];
            if (i != 0 || j != 0) {
                double zq = s.depth.at(0, qx, qy);
                // eps of the implementation: 1e-5 z_p + 1e-8 (float depth noise floor)
                double wz =
                    std::exp(-std::fabs(zp - zq) /
                             (sigmaZ * std::fabs(gradX * i + gradY * j) + 1e-5 * zp + 1e-8));
                double dot = 0;
                for (int c = 0; c < 3; ++c)
                    dot += double(s.normal.at(c, px, py)) * s.normal.at(c, qx, qy);
                double wn = std::pow(std::max(0.0, dot), sigmaN);
                double wl =
                    std::exp(-std::fabs(lp - lum(qx, qy)) / (sigmaL * std::sqrt(gVar) + 1e-10));
                w *= wz * wn * wl;
            }
            sw += w;
            sc += w * lum(qx, qy);
            sv += w * w * s.var.at(0, qx, qy);
        }
    const double expectColor = sc / sw, expectVar = sv / (sw * sw);
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(h.out("color").at(c, px, py), expectColor, 1e-4 * expectColor);
    EXPECT_NEAR(h.out("variance").at(0, px, py), expectVar, 2e-4 * expectVar);
    // The case is not degenerate: filtering changed both values noticeably.
    EXPECT_GT(std::fabs(expectColor - lp), 0.02);
    EXPECT_LT(expectVar, 0.5 * s.var.at(0, px, py));
}

// Two halves: near/far depth, perpendicular normals or different object ids, colour 0 | 100.
// The left half's output measures what leaked across the edge.
TEST(ATrous, NoLeakAcrossDepthNormalOrIdEdges) {
    const int w = 16, h = 8;
    auto leftOf = [](int x) { return x < 8; };
    Scene base{grey(w, h, [&](int x, int) { return leftOf(x) ? 0.f : 100.f; }),
               scalar(w, h, [](int, int) { return 1e4f; }),  // huge variance: w_l ~ 1, only the
               scalar(w, h, [](int, int) { return 5.f; }),   // geometry can stop the blur
               normals(w, h, 0, 0, 1), ids(w, h, [](int, int) { return 1; })};
    auto maxLeft = [&](const PassHarness& hr) {
        float m = 0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < 8; ++x) m = std::max(m, hr.out("color").at(0, x, y));
        return m;
    };
    for (int step : {1, 2, 4}) {
        std::map<std::string, ParamValue> p{{"step", int64_t(step)}};
        // Control: without any edge the right side's 100 spreads left (a lot).
        EXPECT_GT(maxLeft(runATrous(base, p)), 10.f);

        Scene depthEdge = base.copy();
        depthEdge.depth = scalar(w, h, [&](int x, int) { return leftOf(x) ? 5.f : 5.5f; });
        EXPECT_LT(maxLeft(runATrous(depthEdge, p)), 1e-6f)
            << "depth edge, step " << step;  // measured 0

        Scene normalEdge = base.copy();
        normalEdge.normal = grey(w, h, [](int, int) { return 0.f; });
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                // 60 degrees apart: max(0, cos)^128 = 0.5^128 ~ 3e-39
                normalEdge.normal.at(0, x, y) = leftOf(x) ? 0.f : 0.8660254f;
                normalEdge.normal.at(2, x, y) = leftOf(x) ? 1.f : 0.5f;
            }
        EXPECT_LT(maxLeft(runATrous(normalEdge, p)), 1e-6f) << "normal edge, step " << step;

        Scene idEdge = base.copy();
        idEdge.id = ids(w, h, [&](int x, int) { return leftOf(x) ? 1 : 2; });
        EXPECT_LT(maxLeft(runATrous(idEdge, p)), 1e-6f) << "id edge, step " << step;
    }
    // A sloped but continuous surface does blur (the depth gradient tolerance works).
    Scene ramp = base.copy();
    ramp.depth = scalar(w, h, [](int x, int) { return 5.f + 0.2f * float(x); });
    EXPECT_GT(maxLeft(runATrous(ramp, {})), 1.f);
}

TEST_P(ATrousEveryTarget, NonFiniteInputsGiveFiniteOutputs) {
    const int w = 12, h = 9;
    Scene s{grey(w, h, [](int x, int y) { return hash01(x, y); }),
            scalar(w, h, [](int x, int y) { return hash01(x, y, 1); }),
            scalar(w, h, [](int x, int y) { return 1.f + hash01(x, y, 2); }),
            normals(w, h, 0, 1, 0), ids(w, h, [](int, int) { return 0; })};
    s.color.at(0, 3, 3) = NAN;
    s.color.at(1, 5, 5) = INFINITY;
    s.color.at(2, 6, 2) = -INFINITY;
    s.color.at(0, 8, 7) = 1e30f;
    s.var.at(0, 4, 4) = NAN;
    s.var.at(0, 7, 4) = INFINITY;
    s.depth.at(0, 2, 6) = NAN;
    s.depth.at(0, 9, 1) = -INFINITY;
    s.normal.at(1, 6, 6) = NAN;
    s.normal.at(0, 1, 1) = INFINITY;
    for (int step : {1, 4}) {
        auto hr = runATrous(s, {{"step", int64_t(step)}});
        EXPECT_TRUE(allFinite(hr.out("color")));
        EXPECT_TRUE(allFinite(hr.out("variance")));
    }
    auto noVar = runATrous(s, {}, 1, false);
    EXPECT_TRUE(allFinite(noVar.out("color")));
}

// A gentle slope whose depth is stored as half (steps of 0.0625 at 100: flat runs of six pixels,
// then a jump) reads as a stack of depth edges to the plain tolerance, which stops the filter at
// every step; with the loader's depthPrecision fact the filter averages across them.
TEST(ATrous, HalfDepthStepsOnASlopeAreNotEdges) {
    const int w = 64, h = 16;
    auto noise = [](int x, int y) {
        uint32_t v = uint32_t(x) * 73856093u ^ uint32_t(y) * 19349663u;
        v ^= v >> 13;
        v *= 0x5bd1e995u;
        v ^= v >> 15;
        return float(v & 0xffff) / 65535.f - 0.5f;
    };
    Scene s{grey(w, h, [&](int x, int y) { return 0.5f + 0.5f * noise(x, y); }),
            scalar(w, h, [](int, int) { return 1.f; }),  // a luminance weight near 1
            scalar(w, h,
                   [](int x, int y) {
                       return std::round((100.f + 0.01f * float(x + y)) / 0.0625f) * 0.0625f;
                   }),
            normals(w, h, 0, 0, 1), ids(w, h, [](int, int) { return 1; })};
    auto residual = [&](const PassHarness& r) {
        double e = 0;
        for (int y = 4; y < h - 4; ++y)
            for (int x = 8; x < w - 8; ++x) e += std::fabs(r.out("color").at(0, x, y) - 0.5f);
        return e / double((h - 8) * (w - 16));
    };
    const double plain = residual(runATrous(s, {{"step", int64_t(2)}})),
                 half =
                     residual(runATrous(s, {{"step", int64_t(2)}}, 1, true, true, 0.0009765625f));
    std::printf("mean |error| after one step-2 iteration: plain %.4f, half-depth aware %.4f\n",
                plain, half);
    EXPECT_LT(half, 0.85 * plain);  // measured 0.0400 against 0.0506
}

TEST(ATrous, IdenticalWithOneAndTwoThreads) {
    const int w = 67, h = 150;  // several row chunks
    Scene s{
        grey(w, h, [](int x, int y) { return hash01(x, y) * 3.f; }),
        scalar(w, h, [](int x, int y) { return hash01(x, y, 1); }),
        scalar(w, h, [](int x, int y) { return 1.f + 0.01f * float(x) + (y > 70 ? 2.f : 0.f); }),
        normals(w, h, 0, 0.6f, 0.8f), ids(w, h, [](int x, int) { return x / 20; })};
    for (int step : {1, 8}) {
        auto a = runATrous(s, {{"step", int64_t(step)}}, 1);
        auto b = runATrous(s, {{"step", int64_t(step)}}, 2);
        EXPECT_TRUE(sameBits(a.out("color"), b.out("color")));
        EXPECT_TRUE(sameBits(a.out("variance"), b.out("variance")));
    }
}

TEST(ATrous, WithoutVarianceUsesSigmaColor) {
    const int w = 9, h = 3;
    // Luminance step of 1: with sigmaColor 1e-3 nothing crosses, with 1e3 almost everything does.
    Scene s = flatScene(w, h, 0.f, 0.f);
    s.color = grey(w, h, [](int x, int) { return x < 4 ? 0.f : 1.f; });
    auto tight = runATrous(s, {{"sigmaColor", 1e-3}}, 1, false);
    auto loose = runATrous(s, {{"sigmaColor", 1e3}}, 1, false);
    EXPECT_LT(tight.out("color").at(0, 3, 1), 1e-6f);
    EXPECT_GT(loose.out("color").at(0, 3, 1), 0.2f);
}

TEST(ATrous, StepLargerThanImageIsIdentity) {
    Scene s = flatScene(6, 5, 0.f, 0.5f);
    s.color = grey(6, 5, [](int x, int y) { return float(x + 10 * y); });
    auto hr = runATrous(s, {{"step", int64_t(8)}});
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 6; ++x) {
            EXPECT_EQ(hr.out("color").at(1, x, y), float(x + 10 * y));
            EXPECT_FLOAT_EQ(hr.out("variance").at(0, x, y), 0.5f);
        }
}

// Timing at 1080p (run with --gtest_also_run_disabled_tests; not part of CI).

// --- Equivalence of the vectorised pass with the plain scalar reference (ATrousReference.h,
// libm exp/pow). The pass uses px::fastExp2/fastLog2 (stated bounds in PixelMath.h) and fused
// multiply-adds: fastLog2's absolute error (1e-6) times sigmaN = 128 alone moves a weight by
// ~1e-4 relative, and the variance carries w^2. Tolerance 1e-3 relative to |reference| + 1e-3
// (colour) and to |reference| + 1e-6 (variance, strictly positive here); measured worst:
// 1.4e-4 / 1.8e-4 on random inputs, 4.9e-4 / 2.7e-4 with extremes (printed by the test).
#include "../EquivalenceImages.h"
#include "ATrousReference.h"

namespace {
void expectATrousEquivalent(int w, int h, int step, int seed, bool extreme, int threads,
                            float sigmaN = 128.f, float depthPrecision = 0.f) {
    RandomGBuffer g = randomGBuffer(w, h, seed);
    Image var = scalar(w, h, [&](int x, int y) { return 0.01f + hash01(x, y, seed + 3); });
    if (extreme)
        for (Image* im : {&g.color, &g.depth, &g.normal, &var}) sprinkleExtremes(*im, seed + 11);
    Scene s{clone(g.color), clone(var), clone(g.depth), clone(g.normal), clone(g.ids)};
    auto run = runATrous(s, {{"step", int64_t(step)}, {"sigmaN", double(sigmaN)}}, threads, true,
                         true, depthPrecision);
    Image refC(g.color.extent(), Format::Float3), refV(g.color.extent(), Format::Float);
    reference::ATrousInputs in{&g.color.view(),  &var.view(),   &g.depth.view(),
                               &g.normal.view(), &g.ids.view(), step};
    in.sigmaN = sigmaN;
    in.depthPrecision = float(std::stod(std::to_string(depthPrecision)));  // as the fact says
    reference::atrous(in, refC, &refV.view(), 0, h);
    std::string where;
    const double dc = maxScaledDiff(run.out("color"), refC, 1e-3f, &where);
    EXPECT_LE(dc, 1e-3) << "step " << step << " colour " << where;
    const double dv = maxScaledDiff(run.out("variance"), refV, extreme ? 1.f : 1e-6f, &where);
    EXPECT_LE(dv, 1e-3) << "step " << step << " variance " << where;
    EXPECT_TRUE(allFinite(run.out("color")) && allFinite(run.out("variance")));
    std::printf("step %d sigmaN %g%s: worst scaled difference colour %.2g, variance %.2g\n", step,
                sigmaN, extreme ? " (extreme)" : "", dc, dv);
}
}  // namespace

TEST_P(ATrousEveryTarget, VectorisedMatchesScalarReferenceOnRandomInputs) {
    // 157 columns: vector blocks, row-wise borders and ragged tails for every step.
    for (int step : {1, 2, 4, 8, 16}) expectATrousEquivalent(157, 41, step, step, false, 1);
}

TEST_P(ATrousEveryTarget, VectorisedMatchesScalarReferenceForOtherNormalExponents) {
    // sigma_n 128 has a kernel of its own (seven squarings); a whole exponent takes powInt, a
    // fractional one fastLog2/fastExp2, and 0 drops the normal weight.
    for (float sigmaN : {0.f, 3.f, 10.5f, 64.f})
        for (int step : {1, 4}) expectATrousEquivalent(157, 41, step, step + 5, false, 1, sigmaN);
}

TEST_P(ATrousEveryTarget, VectorisedMatchesScalarReferenceWithHalfDepth) {
    // The depth tolerance widened for depth stored as half (kDepthPrecisionFact).
    for (int step : {1, 4, 16})
        expectATrousEquivalent(157, 41, step, step + 9, false, 1, 128.f, 0.0009765625f);
}

TEST_P(ATrousEveryTarget, BandedFilteringMatchesReferenceAcrossBandSeams) {
    // 150 rows are filtered in three bands of 64 whose halos overlap.
    expectATrousEquivalent(157, 150, 16, 77, false, 2);
    expectATrousEquivalent(157, 150, 1, 78, false, 2);
    expectATrousEquivalent(157, 150, 4, 79, false, 2);
}

TEST(ATrous, ScratchScalesWithTheBandNotTheFrame) {
    const int w = 640, h = 480;
    RandomGBuffer g = randomGBuffer(w, h, 5);
    Scene s{clone(g.color), scalar(w, h, [](int, int) { return 0.1f; }), clone(g.depth),
            clone(g.normal), clone(g.ids)};
    // One NaN: the bands around it are filtered from copies, the largest scratch (where masked
    // loads are available, the other bands read in place with 4 planes).
    s.color.at(0, 5, 200) = std::numeric_limits<float>::quiet_NaN();
    runATrous(s, {{"step", int64_t(16)}}, 2);
    // At most one set per thread, each 13 planes of 64 + 2 * 32 rows of w + 32 + 16 columns
    // (a row, then its margin of the reach plus one vector of up to 16 lanes): well under what
    // one full-frame set (13 planes of 480 rows) would take.
    const size_t fullFrameSet = 13 * size_t(w) * size_t(h) * sizeof(float);
    const size_t bandSet = 13 * (128 + 1) * (size_t(w) + 48) * sizeof(float);
    EXPECT_GT(ScratchPool::bytes(), 0u);
    EXPECT_LE(ScratchPool::bytes(), 2 * bandSet + 2 * 4096);
    EXPECT_LT(ScratchPool::bytes(), fullFrameSet * 6 / 10);
}

// Band scratch cut from the idle planes the plan lends (ScratchArena) gives the same output to
// the bit as the pool's, the planes filled with NaN beforehand (a band reading scratch it did
// not write would show), and leaves the pool as it was: the planes hold every thread's bands.
TEST(ATrous, ScratchFromIdlePlanesGivesTheSameOutput) {
    const int w = 97, h = 400;
    RandomGBuffer g = randomGBuffer(w, h, 9);
    Scene s{clone(g.color), scalar(w, h, [](int, int) { return 0.1f; }), clone(g.depth),
            clone(g.normal), clone(g.ids)};
    for (int64_t step : {1, 16}) {
        const PassHarness own = runATrous(s, {{"step", step}}, 2);
        const size_t pool = ScratchPool::bytes();
        const PassHarness lent = runATrous(s, {{"step", step}}, 2, true, true, 0.f, 2);
        EXPECT_EQ(ScratchPool::bytes(), pool) << "step " << step;
        const float* idle = lent.idlePlanes()[0];
        EXPECT_FALSE(std::all_of(idle, idle + size_t(w) * size_t(h), [](float v) {
            return std::isnan(v);
        })) << "the idle planes were not used";
        for (const char* out : {"color", "variance"}) {
            const Image &a = own.out(out), &b = lent.out(out);
            for (int c = 0; c < a.view().channels(); ++c)
                EXPECT_EQ(std::memcmp(a.view().channel(c), b.view().channel(c),
                                      a.view().pixels() * sizeof(float)),
                          0)
                    << out << " step " << step;
        }
    }
}

TEST_P(ATrousEveryTarget, VectorisedMatchesScalarReferenceOnExtremeInputs) {
    for (int step : {1, 4, 16}) expectATrousEquivalent(157, 41, step, 40 + step, true, 2);
}

// The pass reads clean inputs in place and filters a band again from sanitised copies when any
// of its rows, halo included, holds a value the sanitisers change. Scene `dirty` differs from
// `clean` only by such values, each sanitising to the clean scene's value: the outputs must be
// bit-identical. One kind of value per scene (every component, every bound), so each of the
// kernel's checks is needed. 150 rows are three bands of 64 rows (the last 22); the dirty row
// of each step lies in band 1's own rows (step 16) or band 0's (steps 1, 4) and in the next
// band's halo only, so that band is redone for its halo alone while band 2 (steps 1, 4) or
// band 0 (step 16) reads in place.
namespace {
struct DirtyKind {
    const char* what;
    Image Scene::*plane;
    int channel;
    float clean, dirty;          // px::sanitize*(dirty) == clean
    bool allBackground = false;  // every depth at the background (else 2e10 would weigh as 1e10)
};
}  // namespace

TEST_P(ATrousEveryTarget, ReadingInPlaceAndFromSanitisedCopiesAgree) {
    const int w = 157, h = 150;
    RandomGBuffer g = randomGBuffer(w, h, 21);
    Image var = scalar(w, h, [](int x, int y) { return 0.01f + hash01(x, y, 24); });
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    const DirtyKind kinds[] = {
        {"colour R NaN", &Scene::color, 0, 0.f, nan},
        {"colour G +Inf", &Scene::color, 1, 0.f, inf},
        {"colour B above 1e16", &Scene::color, 2, px::kMaxRadiance, 3e16f},
        {"colour R below -1e16", &Scene::color, 0, -px::kMaxRadiance, -5e16f},
        {"normal X 3", &Scene::normal, 0, 0.f, 3.f},
        {"normal Y NaN", &Scene::normal, 1, 0.f, nan},
        {"normal Z -2.5", &Scene::normal, 2, 0.f, -2.5f},
        {"depth NaN", &Scene::depth, 0, kBackgroundDepth, nan},
        {"depth negative", &Scene::depth, 0, kBackgroundDepth, -1.f},
        {"depth beyond the background", &Scene::depth, 0, kBackgroundDepth, 2e10f, true},
        {"variance negative", &Scene::var, 0, 0.f, -1.f},
        {"variance NaN", &Scene::var, 0, 0.f, nan},
        {"variance above 1e32", &Scene::var, 0, 1e32f, 1e33f},
    };
    const std::pair<int, int> stepRows[] = {{1, 63}, {4, 60}, {16, 127}};
    for (const DirtyKind& kind : kinds) {
        for (const auto& [step, row] : stepRows) {
            Scene clean{clone(g.color), clone(var), clone(g.depth), clone(g.normal), clone(g.ids)};
            if (kind.allBackground)
                std::fill_n(clean.depth.channel(0), size_t(w) * size_t(h), kBackgroundDepth);
            Scene dirty = clean.copy();
            for (int x : {0, 80, w - 1}) {
                (clean.*kind.plane).at(kind.channel, x, row) = kind.clean;
                (dirty.*kind.plane).at(kind.channel, x, row) = kind.dirty;
            }
            auto a = runATrous(clean, {{"step", int64_t(step)}}, 1);
            auto b = runATrous(dirty, {{"step", int64_t(step)}}, 2);
            EXPECT_TRUE(sameBits(a.out("color"), b.out("color"))) << kind.what << ", step " << step;
            EXPECT_TRUE(sameBits(a.out("variance"), b.out("variance")))
                << kind.what << ", step " << step;
            EXPECT_TRUE(allFinite(b.out("color")) && allFinite(b.out("variance")));
        }
    }
}

// The same with the variance bound but its output not wanted (svgf.json's last iteration): the
// variance still weighs the luminance term, so it is still checked; with sigma_n = 0 (normals
// unused) and on an image narrower than a vector.
TEST_P(ATrousEveryTarget, ReadingInPlaceAgreesWithoutVarianceOutputWithoutNormalsAndWhenNarrow) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (const int w : {157, 7}) {
        const int h = 150;
        RandomGBuffer g = randomGBuffer(w, h, 31);
        Image var = scalar(w, h, [](int x, int y) { return 0.01f + hash01(x, y, 34); });
        Scene clean{clone(g.color), clone(var), clone(g.depth), clone(g.normal), clone(g.ids)};
        Scene dirty = clean.copy();
        clean.var.at(0, w - 1, 63) = 0.f;
        dirty.var.at(0, w - 1, 63) = -1.f;
        clean.color.at(0, 0, 10) = 0.f;
        dirty.color.at(0, 0, 10) = nan;
        for (double sigmaN : {128.0, 0.0}) {
            auto run = [&](const Scene& s, int threads) {
                auto hr = PassHarness::make<ATrousPass>(
                    {w, h}, {{"step", int64_t(1)}, {"sigmaN", sigmaN}}, threads);
                hr.bind("color", s.color);
                hr.bind("variance", s.var);
                hr.bind("depth", s.depth);
                hr.bind("normal", s.normal);
                hr.bind("objectId", s.id);
                hr.useOutputs({"color"});
                hr.run();
                return hr;
            };
            auto a = run(clean, 1);
            auto b = run(dirty, 2);
            EXPECT_TRUE(sameBits(a.out("color"), b.out("color")))
                << "width " << w << ", sigmaN " << sigmaN;
            EXPECT_TRUE(allFinite(b.out("color")));
        }
    }
}

TEST(ATrous, ExactParameterRunsThePlainPath) {
    RandomGBuffer g = randomGBuffer(61, 23, 8);
    Image var = scalar(61, 23, [](int x, int y) { return 0.05f + hash01(x, y, 2); });
    Scene s{clone(g.color), clone(var), clone(g.depth), clone(g.normal), clone(g.ids)};
    auto run = runATrous(s, {{"step", int64_t(2)}, {"exact", true}}, 2);
    Image refC(g.color.extent(), Format::Float3), refV(g.color.extent(), Format::Float);
    reference::atrous(
        {&g.color.view(), &var.view(), &g.depth.view(), &g.normal.view(), &g.ids.view(), 2}, refC,
        &refV.view(), 0, 23);
    // The same code; the pass is compiled with -fno-trapping-math, which lets GCC choose other
    // instruction sequences (measured: up to 3.3e-7 relative, a few ulp).
    std::string where;
    EXPECT_LE(maxScaledDiff(run.out("color"), refC, 0.f, &where), 2e-6) << where;
    EXPECT_LE(maxScaledDiff(run.out("variance"), refV, 0.f, &where), 2e-6) << where;
}

// --- Fusion (Pass::executeFused): two A-Trous passes on one G-buffer, filtered as a pair that
// shares each tap's depth, normal and object-id work, give each pass's own result to the bit:
// with its own sigmaL, on clean and on dirty inputs (the pair's band is then re-filtered from
// sanitised copies), with and without the variance, at every step's border handling.
namespace {
struct FusedCase {
    const char* what;
    int width, step;
    bool bindVar, dirty;
    int varOutputs = 3;  ///< which passes output their variance (bit 0: the first), if bound
};

void expectFusedPairMatchesSeparatePasses(const FusedCase& c) {
    const int w = c.width, h = 70;
    RandomGBuffer g = randomGBuffer(w, h, 41);
    RandomGBuffer g2 = randomGBuffer(w, h, 42);  // its colour only: a second signal
    Image var = scalar(w, h, [](int x, int y) { return 0.01f + hash01(x, y, 43); });
    Image var2 = scalar(w, h, [](int x, int y) { return 0.5f * hash01(x, y, 44); });
    if (c.dirty) {
        g2.color.at(1, 3, 20) = std::numeric_limits<float>::quiet_NaN();
        var.at(0, w - 1, 50) = -1.f;
    }
    const std::map<std::string, ParamValue> params[2] = {
        {{"step", int64_t(c.step)}, {"sigmaL", 4.0}, {"sigmaColor", 0.6}},
        {{"step", int64_t(c.step)}, {"sigmaL", 6.5}, {"sigmaColor", 2.0}}};
    const Image* colors[2] = {&g.color, &g2.color};
    const Image* vars[2] = {&var, &var2};
    auto make = [&](int i) {
        auto harness = PassHarness::make<ATrousPass>(g.color.extent(), params[i], 2);
        harness.bind("color", *colors[i]);
        if (c.bindVar) harness.bind("variance", *vars[i]);
        if (!c.bindVar || !(c.varOutputs >> i & 1)) harness.useOutputs({"color"});
        harness.bind("depth", g.depth);  // the same images: a fused pair shares them
        harness.bind("normal", g.normal);
        harness.bind("objectId", g.ids);
        return harness;
    };
    PassHarness a = make(0), b = make(1);
    ASSERT_FALSE(a.pass().fusionKey().empty());
    ASSERT_EQ(a.pass().fusionKey(), b.pass().fusionKey()) << "sigmaL is per signal";
    a.run();
    b.run();
    const Image aColor = clone(a.out("color")), bColor = clone(b.out("color"));
    const bool aHasVar = a.hasOutput("variance"), bHasVar = b.hasOutput("variance");
    ASSERT_EQ(aHasVar, c.bindVar && (c.varOutputs & 1)) << c.what;
    ASSERT_EQ(bHasVar, c.bindVar && (c.varOutputs & 2)) << c.what;
    const Image aVar = aHasVar ? clone(a.out("variance")) : Image();
    const Image bVar = bHasVar ? clone(b.out("variance")) : Image();
    for (PassHarness* harness : {&a, &b})  // the fused run must write every pixel again
        for (const char* port : {"color", "variance"})
            if (harness->hasOutput(port)) {
                const ImageView& o = harness->output(port);
                for (int ch = 0; ch < o.channels(); ++ch)
                    std::fill_n(o.planes[size_t(ch)], o.pixels(),
                                std::numeric_limits<float>::quiet_NaN());
            }
    Pass* passes[2] = {&a.pass(), &b.pass()};
    PassIO* ios[2] = {&a, &b};
    a.pass().executeFused(a.ctx, passes, ios);
    EXPECT_TRUE(sameBits(a.out("color"), aColor)) << c.what;
    EXPECT_TRUE(sameBits(b.out("color"), bColor)) << c.what;
    if (aHasVar) {
        EXPECT_TRUE(sameBits(a.out("variance"), aVar)) << c.what;
    }
    if (bHasVar) {
        EXPECT_TRUE(sameBits(b.out("variance"), bVar)) << c.what;
    }
}
}  // namespace

TEST_P(ATrousEveryTarget, FusedPairGivesEachPassItsOwnResultToTheBit) {
    const FusedCase cases[] = {
        {"step 1", 157, 1, true, false},
        {"step 4", 157, 4, true, false},
        {"step 16", 157, 16, true, false},
        {"dirty inputs", 157, 2, true, true},
        {"no variance", 157, 1, false, false},
        {"narrower than a vector", 7, 1, true, false},
        // A chain's last iteration (no variance output) beside another chain's third.
        {"variance output of the first only", 157, 4, true, false, 1},
        {"variance output of the second only", 157, 4, true, true, 2},
    };
    for (const FusedCase& c : cases) expectFusedPairMatchesSeparatePasses(c);
}

TEST(ATrous, PassesFuseOnlyWithTheSameGeometricSettings) {
    auto key = [](std::map<std::string, ParamValue> p) {
        return PassHarness::make<ATrousPass>({8, 8}, p).pass().fusionKey();
    };
    const std::string base = key({{"step", int64_t(2)}});
    EXPECT_FALSE(base.empty());
    EXPECT_EQ(base, key({{"step", int64_t(2)}, {"sigmaL", 9.0}, {"sigmaColor", 3.0}}));
    EXPECT_NE(base, key({{"step", int64_t(4)}}));
    EXPECT_NE(base, key({{"step", int64_t(2)}, {"sigmaZ", 2.0}}));
    EXPECT_NE(base, key({{"step", int64_t(2)}, {"sigmaN", 64.0}}));
    EXPECT_TRUE(key({{"step", int64_t(2)}, {"exact", true}}).empty());
}
