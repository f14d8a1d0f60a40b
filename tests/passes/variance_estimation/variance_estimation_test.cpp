#include <gtest/gtest.h>
#include <kestrel/PixelMath.h>

#include <cstdio>

#include "../SameBits.h"
#include "../SvgfTestImages.h"
#include "HwyTargets.h"
#include "VarianceEstimationPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

// The tests of the vector kernel (against the scalar reference, or against itself) run once per
// compiled SIMD target this CPU supports.
class VarianceEveryTarget : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(VarianceEveryTarget);

namespace {
struct In {
    Image color, moments, length, var, depth, normal;
};
In uniform(int w, int h, float c, float m1, float m2, float len) {
    In in{constant(w, h, Format::Float3, c),  Image(w, h, Format::Float2),
          constant(w, h, Format::Float, len), constant(w, h, Format::Float, 0.123f),
          constant(w, h, Format::Float, 4.f), normals(w, h, 0, 0, 1)};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            in.moments.at(0, x, y) = m1;
            in.moments.at(1, x, y) = m2;
        }
    return in;
}
PassHarness run(const In& in, int threads = 1) {
    auto h = PassHarness::make<VarianceEstimationPass>(in.color.extent(), {}, threads);
    h.bind("color", in.color);
    h.bind("moments", in.moments);
    h.bind("historyLength", in.length);
    h.bind("variance", in.var);
    h.bind("depth", in.depth);
    h.bind("normal", in.normal);
    h.run();
    return h;
}
}  // namespace

TEST(VarianceEstimation, ShortHistoryUsesBoostedSpatialMoments) {
    for (float len : {1.f, 2.f}) {
        In in = uniform(9, 9, 0.5f, 1.f, 1.5f, len);
        auto h = run(in);
        // (m2 - m1^2) * 4 / historyLength = 0.5 * 4 / len
        EXPECT_NEAR(h.out("variance").at(0, 4, 4), 2.f / len, 1e-5f);
        EXPECT_NEAR(h.out("color").at(1, 4, 4), 0.5f, 1e-6f);  // constant stays constant
    }
}

TEST(VarianceEstimation, LongHistoryPassesThrough) {
    In in = uniform(5, 5, 0.5f, 1.f, 1.5f, 4.f);
    in.color.at(0, 2, 2) = 7.f;
    auto h = run(in);
    EXPECT_FLOAT_EQ(h.out("variance").at(0, 2, 2), 0.123f);
    EXPECT_FLOAT_EQ(h.out("color").at(0, 2, 2), 7.f);
}

TEST(VarianceEstimation, NoLeakAcrossDepthEdge) {
    const int w = 14, h = 7;
    In in = uniform(w, h, 0.f, 0.f, 0.f, 1.f);
    for (int y = 0; y < h; ++y)
        for (int x = 7; x < w; ++x) {
            in.depth.at(0, x, y) = 9.f;
            for (int c = 0; c < 3; ++c) in.color.at(c, x, y) = 0.05f;  // little luminance step
            in.moments.at(0, x, y) = 100.f;
            in.moments.at(1, x, y) = 20000.f;
        }
    auto hr = run(in);
    float leak = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < 7; ++x)
            leak = std::max({leak, hr.out("variance").at(0, x, y), hr.out("color").at(0, x, y)});
    EXPECT_LT(leak, 1e-6f);  // measured 0: constant depth per side, slope 0, weight exactly 0
}

TEST_P(VarianceEveryTarget, NonFiniteInputsGiveFiniteOutputs) {
    In in = uniform(6, 6, 0.5f, 1.f, 1.5f, 1.f);
    in.color.at(0, 1, 1) = NAN;
    in.moments.at(1, 2, 2) = INFINITY;
    in.moments.at(0, 3, 3) = NAN;
    in.length.at(0, 4, 4) = NAN;
    in.depth.at(0, 2, 3) = NAN;
    in.normal.at(2, 3, 2) = NAN;
    in.var.at(0, 0, 0) = NAN;
    auto h = run(in);
    EXPECT_TRUE(allFinite(h.out("color")));
    EXPECT_TRUE(allFinite(h.out("variance")));
}

TEST(VarianceEstimation, IdenticalWithOneAndTwoThreads) {
    const int w = 33, hgt = 140;
    In in = uniform(w, hgt, 0.f, 0.f, 0.f, 1.f);
    in.color = grey(w, hgt, [](int x, int y) { return hash01(x, y); });
    in.length =
        scalar(w, hgt, [](int x, int y) { return 1.f + std::floor(6.f * hash01(x, y, 2)); });
    in.depth =
        scalar(w, hgt, [](int x, int y) { return 3.f + 0.02f * float(x) + (y > 60 ? 1.f : 0.f); });
    for (int y = 0; y < hgt; ++y)
        for (int x = 0; x < w; ++x) {
            in.moments.at(0, x, y) = hash01(x, y);
            in.moments.at(1, x, y) = hash01(x, y) * hash01(x, y) + hash01(x, y, 5);
        }
    auto a = run(in, 1), b = run(in, 2);
    EXPECT_TRUE(sameBits(a.out("color"), b.out("color")));
    EXPECT_TRUE(sameBits(a.out("variance"), b.out("variance")));
}

// --- Equivalence of the vectorised pass with the plain scalar reference (VarianceReference.h).
// The pass evaluates exp and pow with px::fastExp2 / px::fastLog2 (relative error < 2e-5 and
// absolute < 1e-6 in the exponent, times sigmaN = 128) and fused multiply-adds; the reference
// uses libm. Measured worst differences (colour, variance): 1.3e-5, 5.5e-5 on random inputs;
// the tolerance is 1e-4 relative to |reference| + 1 (colour) or + 4 max m2 (variance, whose
// m2 - m1^2 cancels).
#include <optional>

#include "../EquivalenceImages.h"
#include "VarianceReference.h"

namespace {
struct EqCase {
    RandomGBuffer g;
    Image moments, length, var;
};
/// `sparse`: short history only at isolated pixels (about 1 in 60), so most vector blocks are
/// not prepared and each prepared one sits between unprepared neighbours.
EqCase equivalenceCase(int w, int h, int seed, bool extreme, bool sparse = false) {
    EqCase e{randomGBuffer(w, h, seed), Image(w, h, Format::Float2), Image(w, h, Format::Float),
             Image(w, h, Format::Float)};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float l =
                px::luminance(e.g.color.at(0, x, y), e.g.color.at(1, x, y), e.g.color.at(2, x, y));
            e.moments.at(0, x, y) = l;
            e.moments.at(1, x, y) = l * l * (1.f + hash01(x, y, seed + 50));
            // Short history in blobs and stripes, long elsewhere: both paths, all block phases.
            const bool isShort = sparse ? hash01(x, y, seed + 53) < 1.f / 60.f
                                        : hash01(x / 5, y / 3, seed + 51) < 0.6f;
            e.length.at(0, x, y) = isShort ? 1.f + float(x % 3) : 8.f;
            e.var.at(0, x, y) = hash01(x, y, seed + 52);
        }
    if (extreme)
        for (Image* im : {&e.g.color, &e.g.depth, &e.g.normal, &e.moments, &e.length, &e.var})
            sprinkleExtremes(*im, seed + 7);
    return e;
}
/// The pass run on the case (its own defaults, but for sigmaL when given).
PassHarness runCase(const EqCase& e, int threads = 1, std::optional<float> sigmaL = {}) {
    std::map<std::string, ParamValue> params;
    if (sigmaL) params["sigmaL"] = double(*sigmaL);
    auto h = PassHarness::make<VarianceEstimationPass>(e.g.color.extent(), params, threads);
    h.bind("color", e.g.color);
    h.bind("moments", e.moments);
    h.bind("historyLength", e.length);
    h.bind("variance", e.var);
    h.bind("depth", e.g.depth);
    h.bind("normal", e.g.normal);
    h.bind("objectId", e.g.ids);
    h.run();
    return h;
}
void expectEquivalent(const EqCase& e, int threads, double tol, float sigmaL = 0.f) {
    const Extent ext = e.g.color.extent();
    auto h = runCase(e, threads, sigmaL);
    Image refC(ext, Format::Float3), refV(ext, Format::Float);
    reference::VarianceInputs in{&e.g.color.view(), &e.moments.view(), &e.length.view(),
                                 &e.var.view(),     &e.g.depth.view(), &e.g.normal.view(),
                                 &e.g.ids.view()};
    in.sigmaL = sigmaL;
    reference::varianceEstimation(in, refC, &refV.view(), 0, ext.height);
    float maxM2 = 0;
    for (size_t i = 0; i < ext.pixels(); ++i)
        maxM2 = std::max(maxM2, px::sanitizePositive(e.moments.channel(1)[i], 1e32f));
    std::string where;
    const double dc = maxScaledDiff(h.out("color"), refC, 1.f, &where);
    EXPECT_LE(dc, tol) << "colour " << where;
    const double dv = maxScaledDiff(h.out("variance"), refV, 4.f * maxM2, &where);
    EXPECT_LE(dv, tol) << "variance " << where;
    EXPECT_TRUE(allFinite(h.out("color")));
    EXPECT_TRUE(allFinite(h.out("variance")));
    std::printf("worst scaled difference: colour %.2g, variance %.2g\n", dc, dv);
}
}  // namespace

TEST_P(VarianceEveryTarget, VectorisedMatchesScalarReferenceOnRandomInputs) {
    // 77 columns: vector blocks, scalar borders and a ragged tail for 4-, 8- and 16-lane targets.
    expectEquivalent(equivalenceCase(77, 29, 1, false), 1, 1e-4);
    // 100 rows: four bands of 32 rows (prepared separately, with overlapping halos).
    expectEquivalent(equivalenceCase(77, 100, 4, false), 2, 1e-4);
}

TEST_P(VarianceEveryTarget, VectorisedMatchesScalarReferenceWhereFewPixelsAreShort) {
    // The steady state: only the blocks around short pixels are prepared (a preparation that
    // missed a tap's column would read another band's stale scratch and differ).
    expectEquivalent(equivalenceCase(301, 70, 5, false, true), 1, 1e-4);
    expectEquivalent(equivalenceCase(301, 70, 6, true, true), 2, 1e-4);
}

TEST_P(VarianceEveryTarget, VectorisedMatchesScalarReferenceWithALuminanceTerm) {
    expectEquivalent(equivalenceCase(77, 29, 8, false), 2, 1e-4, 10.f);  // Falcor's phiColor
    expectEquivalent(equivalenceCase(77, 29, 9, true), 1, 1e-4, 0.5f);
}

// The spatial estimate scales with the render: 1000x the light gives 1000x the colour and 1e6x
// the variance, so a render's exposure does not decide how much it is filtered. With Falcor's
// absolute luminance term (sigmaL 10) svgf.json lost 2.5 dB on blender-street made 1000x
// brighter, 8 dB on blender-street-defaults.
TEST(VarianceEstimation, SpatialEstimateIsTheSameAtAnyExposure) {
    EqCase e = equivalenceCase(40, 24, 11, false), bright = equivalenceCase(40, 24, 11, false);
    for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 40; ++x) {
            for (int c = 0; c < 3; ++c) bright.g.color.at(c, x, y) *= 1000.f;
            bright.moments.at(0, x, y) *= 1000.f;
            bright.moments.at(1, x, y) *= 1e6f;
            bright.var.at(0, x, y) *= 1e6f;
        }
    auto a = runCase(e), b = runCase(bright);
    for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 40; ++x) {
            const float v = a.out("variance").at(0, x, y);
            EXPECT_NEAR(b.out("variance").at(0, x, y), 1e6f * v, 1e-3f * (1e6f * v + 1.f))
                << x << "," << y;
            const float c = a.out("color").at(0, x, y);
            EXPECT_NEAR(b.out("color").at(0, x, y), 1000.f * c, 1e-3f * (1000.f * c + 1.f))
                << x << "," << y;
        }
}

TEST_P(VarianceEveryTarget, VectorisedMatchesScalarReferenceOnExtremeInputs) {
    // Without a luminance term the 1e15 extremes are averaged with O(1) neighbours, so the fast
    // exp2/log2 weights' relative error (~2e-5, times sigmaN in the normal term) shows against
    // |reference| + 1, more where +-1e30 taps cancel in one window: measured 3.7e-4 (AVX2,
    // AVX3; SSE4 9.6e-5) with tests/ExtremeValues.h's list, 5e-4 allowed. Random inputs stay
    // within 1e-4.
    expectEquivalent(equivalenceCase(77, 29, 2, true), 2, 5e-4);
}

TEST_P(VarianceEveryTarget, SameOutputForOneAndTwoThreads) {
    EqCase e = equivalenceCase(77, 29, 3, true);
    auto runWith = [&](int threads) {
        auto h = PassHarness::make<VarianceEstimationPass>(e.g.color.extent(), {}, threads);
        h.bind("color", e.g.color);
        h.bind("moments", e.moments);
        h.bind("historyLength", e.length);
        h.bind("variance", e.var);
        h.bind("depth", e.g.depth);
        h.bind("normal", e.g.normal);
        h.bind("objectId", e.g.ids);
        h.run();
        return std::make_pair(clone(h.out("color")), clone(h.out("variance")));
    };
    auto a = runWith(1), b = runWith(2);
    EXPECT_TRUE(sameBits(a.first, b.first));
    EXPECT_TRUE(sameBits(a.second, b.second));
}

TEST(VarianceEstimation, ExactParameterRunsThePlainPath) {
    EqCase e = equivalenceCase(40, 20, 9, false);
    auto h = PassHarness::make<VarianceEstimationPass>(e.g.color.extent(), {{"exact", true}}, 2);
    h.bind("color", e.g.color);
    h.bind("moments", e.moments);
    h.bind("historyLength", e.length);
    h.bind("variance", e.var);
    h.bind("depth", e.g.depth);
    h.bind("normal", e.g.normal);
    h.bind("objectId", e.g.ids);
    h.run();
    Image refC(e.g.color.extent(), Format::Float3), refV(e.g.color.extent(), Format::Float);
    reference::VarianceInputs in{&e.g.color.view(), &e.moments.view(), &e.length.view(),
                                 &e.var.view(),     &e.g.depth.view(), &e.g.normal.view(),
                                 &e.g.ids.view()};
    reference::varianceEstimation(in, refC, &refV.view(), 0, 20);
    EXPECT_TRUE(sameBits(h.out("color"), refC));
    EXPECT_TRUE(sameBits(h.out("variance"), refV));
}

// --- Two chains on one G-buffer run as a fused pair (executeFused): each tap weighed once for
// both. Each must get, to the bit, what it gets alone, whether its short pixels coincide with
// the other's or not, with its own minHistoryLength, and with the variance output unconsumed.
namespace {
struct PairCase {
    const char* what;
    int width;
    bool extreme, sparse;
    bool secondVariance = true;  ///< whether the second pass's variance output is consumed
    double secondMinHistory = 4.0;
    double sigmaN = 128.0;  ///< 128: squarings; other values take the power or log2 paths
    bool ids = true;        ///< objectId bound
    int idlePlanes = 0;     ///< planes lent as scratch (NaN-filled), as the engine lends them
};

void expectFusedPairMatchesSeparatePasses(const PairCase& c) {
    SCOPED_TRACE(c.what);
    const EqCase e0 = equivalenceCase(c.width, 70, 21, c.extreme, c.sparse);
    const EqCase e1 = equivalenceCase(c.width, 70, 22, c.extreme, !c.sparse);  // its signal only
    auto make = [&](const EqCase& e, double minHistory, bool variance) {
        auto h = PassHarness::make<VarianceEstimationPass>(
            e0.g.color.extent(), {{"minHistoryLength", minHistory}, {"sigmaN", c.sigmaN}}, 2);
        if (c.idlePlanes) h.lendIdlePlanes(c.idlePlanes, NAN);
        h.bind("color", e.g.color);
        h.bind("moments", e.moments);
        h.bind("historyLength", e.length);
        h.bind("variance", e.var);
        h.bind("depth", e0.g.depth);  // the same images: a fused pair shares them
        h.bind("normal", e0.g.normal);
        if (c.ids) h.bind("objectId", e0.g.ids);
        if (!variance) h.useOutputs({"color"});
        return h;
    };
    PassHarness a = make(e0, 4.0, true), b = make(e1, c.secondMinHistory, c.secondVariance);
    ASSERT_FALSE(a.pass().fusionKey().empty());
    ASSERT_EQ(a.pass().fusionKey(), b.pass().fusionKey());
    a.run();
    b.run();
    const Image aColor = clone(a.out("color")), bColor = clone(b.out("color")),
                aVar = clone(a.out("variance"));
    const std::optional<Image> bVar =
        c.secondVariance ? std::optional<Image>(clone(b.out("variance"))) : std::nullopt;
    for (PassHarness* h : {&a, &b})  // the fused run must write every pixel again
        for (const char* port : {"color", "variance"})
            if (h->hasOutput(port)) {
                const ImageView& o = h->output(port);
                for (int ch = 0; ch < o.channels(); ++ch)
                    std::fill_n(o.planes[size_t(ch)], o.pixels(), NAN);
            }
    Pass* passes[2] = {&a.pass(), &b.pass()};
    PassIO* ios[2] = {&a, &b};
    a.pass().executeFused(a.ctx, passes, ios);
    EXPECT_TRUE(sameBits(a.out("color"), aColor));
    EXPECT_TRUE(sameBits(a.out("variance"), aVar));
    EXPECT_TRUE(sameBits(b.out("color"), bColor));
    if (bVar) {
        EXPECT_TRUE(sameBits(b.out("variance"), *bVar));
    }
}
}  // namespace

TEST_P(VarianceEveryTarget, FusedPairGivesEachPassItsOwnResultToTheBit) {
    const PairCase cases[] = {
        {"short pixels in blobs beside isolated ones", 157, false, false},
        {"isolated short pixels beside blobs", 157, false, true},
        {"extreme inputs", 157, true, false},
        {"narrower than a vector", 7, false, false},
        {"second variance unconsumed", 157, false, false, false},
        {"second with its own minHistoryLength", 157, false, false, true, 2.5},
        {"a whole exponent not a power of two", 157, false, false, true, 4.0, 100.0},
        {"a fractional exponent (log2)", 157, false, false, true, 4.0, 64.5},
        {"no normal term", 157, false, false, true, 4.0, 0.0},
        {"no object ids", 157, false, false, true, 4.0, 128.0, false},
        {"scratch in lent idle planes", 157, true, false, true, 4.0, 128.0, true, 20},
    };
    for (const PairCase& c : cases) expectFusedPairMatchesSeparatePasses(c);
}

TEST(VarianceEstimation, PassesFuseOnlyWithTheSameWeights) {
    auto key = [](std::map<std::string, ParamValue> p) {
        return PassHarness::make<VarianceEstimationPass>({8, 8}, p).pass().fusionKey();
    };
    const std::string base = key({});
    EXPECT_FALSE(base.empty());
    EXPECT_EQ(base, key({{"minHistoryLength", 2.0}}));  // per signal
    EXPECT_NE(base, key({{"sigmaZ", 2.0}}));
    EXPECT_NE(base, key({{"sigmaN", 64.0}}));
    EXPECT_TRUE(key({{"sigmaL", 10.0}}).empty());  // a luminance term: weights per signal
    EXPECT_TRUE(key({{"exact", true}}).empty());
}
