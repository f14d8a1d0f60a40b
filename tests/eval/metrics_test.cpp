// Error metrics: hand-computed values on tiny images, SSIM against its closed form and a
// brute-force 2D evaluation, NaN/Inf accounting, and the speed of a 1080p SSIM.
#include <eval/Metrics.h>
#include <gtest/gtest.h>
#include <kestrel/Error.h>

#include <cmath>
#include <ctime>
#include <limits>
#include <random>
#include <vector>

using namespace kestrel;
using namespace kestrel::eval;

namespace {

Image rgb(int w, int h, std::initializer_list<float> values) {
    Image img(w, h, Format::Float3);
    auto it = values.begin();
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) img.at(c, x, y) = *it++;
    return img;
}

Image constant(int w, int h, float v) {
    Image img(w, h, Format::Float3);
    img.fill(v);
    return img;
}

// A smooth-plus-noise texture in [0.2, 0.8].
Image texture(int w, int h, unsigned seed) {
    Image img(w, h, Format::Float3);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-0.1f, 0.1f);
    for (int c = 0; c < 3; ++c)
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                img.at(c, x, y) = 0.5f + 0.2f * std::sin(0.3f * x + 0.2f * y + c) + u(rng);
    return img;
}

// Brute-force SSIM: the 11x11 Gaussian (sigma 1.5) window truncated to the image and
// renormalised, moments in double, Wang et al. 2004 eq. 13, averaged over pixels and channels.
double bruteSsim(const Image& a, const Image& b) {
    const int w = a.width(), h = a.height();
    const double c1 = 1e-4, c2 = 9e-4;
    double total = 0;
    for (int c = 0; c < 3; ++c)
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                double ws = 0, mx = 0, my = 0, xx = 0, yy = 0, xy = 0;
                for (int dy = -5; dy <= 5; ++dy)
                    for (int dx = -5; dx <= 5; ++dx) {
                        const int i = x + dx, j = y + dy;
                        if (i < 0 || j < 0 || i >= w || j >= h) continue;
                        const double g = std::exp(-(dx * dx + dy * dy) / (2 * 1.5 * 1.5));
                        const double p = a.at(c, i, j), q = b.at(c, i, j);
                        ws += g, mx += g * p, my += g * q;
                        xx += g * p * p, yy += g * q * q, xy += g * p * q;
                    }
                mx /= ws, my /= ws, xx = xx / ws - mx * mx, yy = yy / ws - my * my;
                xy = xy / ws - mx * my;
                total += (2 * mx * my + c1) * (2 * xy + c2) /
                         ((mx * mx + my * my + c1) * (xx + yy + c2));
            }
    return total / (3.0 * w * h);
}

}  // namespace

TEST(Metrics, RelMseHandComputed) {
    // Pixel 0: (1 - 0)^2 / (0 + 0.01) = 100 per channel; pixel 1: (0 - 1)^2 / (1 + 0.01).
    Image out = rgb(2, 1, {1, 1, 1, 0, 0, 0});
    Image ref = rgb(2, 1, {0, 0, 0, 1, 1, 1});
    EXPECT_NEAR(relMse(out, ref), (100.0 + 1.0 / 1.01) / 2.0, 1e-9);
    EXPECT_EQ(relMse(ref, ref), 0.0);
}

TEST(Metrics, PsnrHandComputed) {
    // Clamp tone map: MSE = 3 * 0.1^2 / 6 = 0.005 -> 10 log10(200) = 23.0103 dB.
    Image out = rgb(2, 1, {0.5f, 0.5f, 0.5f, 0, 0, 0});
    Image ref = rgb(2, 1, {0.6f, 0.6f, 0.6f, 0, 0, 0});
    FrameMetrics m = compareImages(out, ref, ToneMap::Clamp);
    EXPECT_NEAR(m.psnr, 10 * std::log10(200.0), 1e-4);
    // Identical images: PSNR capped at 100 dB instead of +inf.
    EXPECT_DOUBLE_EQ(compareImages(ref, ref, ToneMap::Clamp).psnr, 100.0);
}

TEST(Metrics, ToneMaps) {
    EXPECT_FLOAT_EQ(toneMap(ToneMap::Reinhard, 1.0f), std::pow(0.5f, 1 / 2.2f));
    EXPECT_FLOAT_EQ(toneMap(ToneMap::Reinhard, 3.0f), std::pow(0.75f, 1 / 2.2f));
    EXPECT_FLOAT_EQ(toneMap(ToneMap::Reinhard, -2.0f), 0.0f);
    EXPECT_FLOAT_EQ(toneMap(ToneMap::Reinhard, std::numeric_limits<float>::infinity()), 1.0f);
    EXPECT_FLOAT_EQ(toneMap(ToneMap::Reinhard, std::numeric_limits<float>::quiet_NaN()), 0.0f);
    EXPECT_FLOAT_EQ(toneMap(ToneMap::Clamp, 7.0f), 1.0f);
    EXPECT_NEAR(toneMap(ToneMap::Srgb, 0.5f), 0.735357f, 1e-5);  // sRGB OETF of 0.5
    EXPECT_FLOAT_EQ(toneMap(ToneMap::Srgb, 0.001f), 0.01292f);   // linear segment
    EXPECT_EQ(parseToneMap("srgb"), ToneMap::Srgb);
    EXPECT_FALSE(parseToneMap("aces").has_value());
}

TEST(Metrics, SsimOfIdenticalImagesIsOne) {
    Image a = texture(37, 23, 1);
    EXPECT_NEAR(ssim(a, a), 1.0, 1e-6);
    Image tiny = texture(3, 2, 2);  // smaller than the window
    EXPECT_NEAR(ssim(tiny, tiny), 1.0, 1e-6);
}

TEST(Metrics, SsimConstantOffsetMatchesLuminanceTerm) {
    // Constant images: sigma = 0, so SSIM = (2 a b + C1) / (a^2 + b^2 + C1) exactly.
    const double a = 0.3, b = 0.5, c1 = 1e-4;
    EXPECT_NEAR(ssim(constant(20, 15, float(a)), constant(20, 15, float(b))),
                (2 * a * b + c1) / (a * a + b * b + c1), 1e-6);

    // Textured image plus an offset d: variances are equal and the structure identical, so the
    // contrast-structure term is 1 and SSIM is the mean over windows of the luminance term
    // (2 mu (mu + d) + C1) / (mu^2 + (mu + d)^2 + C1) with mu the window mean.
    const float d = 0.15f;
    Image x = texture(31, 19, 3), y(x.extent(), Format::Float3);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < x.extent().pixels(); ++i) y.channel(c)[i] = x.channel(c)[i] + d;
    double expected = 0;
    for (int c = 0; c < 3; ++c)
        for (int j = 0; j < x.height(); ++j)
            for (int i = 0; i < x.width(); ++i) {
                double ws = 0, mu = 0;
                for (int dy = -5; dy <= 5; ++dy)
                    for (int dx = -5; dx <= 5; ++dx) {
                        if (i + dx < 0 || j + dy < 0 || i + dx >= x.width() || j + dy >= x.height())
                            continue;
                        const double g = std::exp(-(dx * dx + dy * dy) / 4.5);
                        ws += g, mu += g * x.at(c, i + dx, j + dy);
                    }
                mu /= ws;
                expected += (2 * mu * (mu + d) + c1) / (mu * mu + (mu + d) * (mu + d) + c1);
            }
    expected /= 3.0 * x.width() * x.height();
    EXPECT_NEAR(ssim(x, y), expected, 1e-4);
    EXPECT_LT(expected, 0.97);  // the offset is visible: 0.9597 here
}

TEST(Metrics, SsimMatchesBruteForceSymmetricAndBelowOneForNoise) {
    Image a = texture(29, 21, 4), b = texture(29, 21, 4);
    std::mt19937 rng(9);
    std::normal_distribution<float> noise(0.0f, 0.1f);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < b.extent().pixels(); ++i) b.channel(c)[i] += noise(rng);
    const double ab = ssim(a, b), ba = ssim(b, a);
    EXPECT_NEAR(ab, ba, 1e-6);
    EXPECT_NEAR(ab, bruteSsim(a, b), 1e-4);
    EXPECT_LT(ab, 0.9);  // measured 0.62 for noise sigma 0.1 on this texture
    EXPECT_GT(ab, 0.2);
}

TEST(Metrics, TemporalInstability) {
    Image r0 = texture(16, 9, 5), r1 = texture(16, 9, 6), o0 = texture(16, 9, 7);
    // o1 = o0 + (r1 - r0): the output changes exactly like the reference.
    Image o1(r0.extent(), Format::Float3);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < r0.extent().pixels(); ++i)
            o1.channel(c)[i] = o0.channel(c)[i] + (r1.channel(c)[i] - r0.channel(c)[i]);
    EXPECT_NEAR(temporalInstability(o1, o0, r1, r0), 0.0, 1e-6);
    // A static output while the reference brightens by 0.1 everywhere: instability 0.1.
    Image s = constant(16, 9, 0.4f), ra = constant(16, 9, 0.2f), rb = constant(16, 9, 0.3f);
    EXPECT_NEAR(temporalInstability(s, s, rb, ra), 0.1, 1e-6);
}

TEST(Metrics, CompareImagesTemporalOnlyWithPrevious) {
    Image a = texture(12, 12, 1), b = texture(12, 12, 2);
    FrameImages f0, f1;
    FrameMetrics m0 = compareImages(a, b, ToneMap::Reinhard, nullptr, &f0);
    EXPECT_FALSE(m0.temporal.has_value());
    FrameMetrics m1 = compareImages(a, b, ToneMap::Reinhard, &f0, &f1);
    ASSERT_TRUE(m1.temporal.has_value());
    EXPECT_NEAR(*m1.temporal, 0.0, 1e-9);  // nothing changed in either sequence
    EXPECT_GT(f1.outDisplay.width(), 0);
}

TEST(Metrics, NonFiniteInputsAreCountedAndMetricsStayFinite) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    Image out = rgb(3, 1, {nan, 0.5f, 0.5f, 0.5f, inf, 0.5f, 0.5f, 0.5f, 0.5f});
    Image ref = rgb(3, 1, {0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, -inf});
    FrameMetrics m = compareImages(out, ref, ToneMap::Reinhard);
    EXPECT_EQ(m.nonFiniteOutput, 2u);
    EXPECT_EQ(m.nonFiniteReference, 1u);
    EXPECT_TRUE(std::isfinite(m.relMse));
    EXPECT_GT(m.relMse, 1e60);  // the Inf output is a huge (FLT_MAX-sized) error, not hidden
    EXPECT_TRUE(std::isfinite(m.psnr));
    EXPECT_TRUE(std::isfinite(m.ssim));
}

TEST(Metrics, SizeMismatchAndNonRgbAreErrors) {
    EXPECT_THROW(relMse(constant(4, 4, 0), constant(4, 5, 0)), kestrel::Error);
    Image gray(4, 4, Format::Float);
    EXPECT_THROW(compareImages(gray, gray, ToneMap::Clamp), kestrel::Error);
}

TEST(Metrics, Ssim1080pIsFast) {
    Image a = texture(1920, 1080, 1), b = texture(1920, 1080, 2);
    // CPU time of this (single-threaded) call, so that other processes on a shared machine do
    // not count against it.
    const std::clock_t t0 = std::clock();
    const double s = ssim(a, b);
    const double sec = double(std::clock() - t0) / CLOCKS_PER_SEC;
    EXPECT_TRUE(std::isfinite(s));
    // Measured ~0.1 s of CPU (Release); the bound leaves room for a slow CI core.
    EXPECT_LT(sec, 1.0) << "SSIM of a 1080p RGB image took " << sec << " s of CPU";
}

// Speckles: an isolated dark pixel on a lit surface counts; the same pixel where the reference
// is dark too, a dark region the output's neighbours share (a shadow edge), and a dim but not
// dark pixel (0.5x the reference) do not.
TEST(Speckles, IsolatedDarkPixelOnLitSurfaceCounts) {
    const Image ref = constant(5, 5, 1.0f);
    Image out = constant(5, 5, 1.0f);
    for (int c = 0; c < 3; ++c) out.at(c, 2, 2) = 0.1f;
    const std::vector<uint8_t> mask = speckleMask(out, ref);
    EXPECT_EQ(mask[2 * 5 + 2], 1);
    size_t count = 0;
    for (uint8_t m : mask) count += m;
    EXPECT_EQ(count, 1u);
    EXPECT_DOUBLE_EQ(specklesPerMegapixel(mask), 1e6 / 25.0);
    EXPECT_DOUBLE_EQ(compareImages(out, ref, ToneMap::Reinhard).speckles, 1e6 / 25.0);
}

TEST(Speckles, DarkReferenceSharedDarknessAndDimPixelsDoNot) {
    Image ref = constant(5, 5, 1.0f), out = constant(5, 5, 1.0f);
    for (int c = 0; c < 3; ++c) out.at(c, 2, 2) = 0.1f, ref.at(c, 2, 2) = 0.01f;  // dark there
    EXPECT_DOUBLE_EQ(specklesPerMegapixel(speckleMask(out, ref)), 0.0);
    Image ref2 = constant(5, 5, 1.0f), out2 = constant(5, 5, 1.0f);
    for (int y = 0; y < 5; ++y)  // a dark left half in the output: its median is dark too
        for (int x = 0; x < 3; ++x)
            for (int c = 0; c < 3; ++c) out2.at(c, x, y) = 0.1f;
    EXPECT_DOUBLE_EQ(specklesPerMegapixel(speckleMask(out2, ref2)), 0.0);
    Image out3 = constant(5, 5, 1.0f);
    for (int c = 0; c < 3; ++c) out3.at(c, 2, 2) = 0.5f;  // dim, not a speckle
    EXPECT_DOUBLE_EQ(specklesPerMegapixel(speckleMask(out3, ref2)), 0.0);
}
