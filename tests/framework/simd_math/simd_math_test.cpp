// SimdMath's vector helpers against their scalar namesakes in PixelMath.h, on the build's
// static Highway target (AVX-512 takes its own fastExp2 path: vscalefps).
#include <gtest/gtest.h>
#include <kestrel/SimdMath.h>

#include <cmath>
#include <cstring>
#include <vector>

using namespace kestrel;
namespace hn = hwy::HWY_NAMESPACE;

namespace {

/// simd::fastExp2 of every value, a vector at a time.
std::vector<float> vectorExp2(const std::vector<float>& xs) {
    const simd::DF d;
    const size_t n = hn::Lanes(d);
    std::vector<float> in(xs), out(xs.size() + n);
    in.resize((xs.size() + n - 1) / n * n, 0.f);
    for (size_t i = 0; i < in.size(); i += n)
        hn::StoreU(simd::fastExp2(hn::LoadU(d, in.data() + i)), d, out.data() + i);
    out.resize(xs.size());
    return out;
}

}  // namespace

TEST(SimdMath, FastExp2MatchesTheScalarForm) {
    // The scalar form's reduction and polynomial; the vector form fuses the multiply-adds, so
    // it is held to exp2 with the stated bound and to the scalar form within a few ulp.
    std::vector<float> xs;
    for (float x = -130.f; x <= 130.f; x += 0.00731f) xs.push_back(x);
    for (float x : {-126.5f, -126.49f, -126.51f, -127.f, -149.f, -200.f, -1e4f, -1e30f, 0.f, -0.5f,
                    0.5f, 126.f, 126.5f, 1e30f})
        xs.push_back(x);
    const std::vector<float> v = vectorExp2(xs);
    double worst = 0;
    for (size_t i = 0; i < xs.size(); ++i) {
        const float x = xs[i], s = px::fastExp2(x);
        if (x < -126.5f) {
            EXPECT_EQ(v[i], 0.f) << x;  // exactly 0: a rejected tap must weigh nothing
            continue;
        }
        if (x >= -126.f && x <= 126.f) {
            const double r = std::fabs(double(v[i]) / std::exp2(double(x)) - 1.0);
            worst = std::max(worst, r);
            ASSERT_LT(r, 3e-7) << x;  // the bound SimdMath.h and PixelMath.h state
        }
        EXPECT_NEAR(v[i], s, 4e-7f * s + 1e-45f) << x;
    }
    EXPECT_EQ(vectorExp2({126.5f, 1e30f})[1], std::exp2(126.f));
    std::printf("simd::fastExp2 (%zu lanes): worst relative error %.2g on [-126, 126]\n",
                hn::Lanes(simd::DF()), worst);
}
