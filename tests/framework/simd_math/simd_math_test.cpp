// SimdMath's vector helpers against their scalar namesakes in PixelMath.h, on every SIMD target
// the build compiles and this CPU runs (AVX-512 takes its own fastExp2 path: vscalefps), and the
// run-time dispatch itself: each target's function is the one called when dispatch is limited
// to that target.
#include <gtest/gtest.h>
#include <kestrel/PixelMath.h>

#include <cmath>
#include <cstdio>
#include <vector>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "simd_math_test.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>
#include <kestrel/SimdMath.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;

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

/// This copy's target and vector width.
int64_t compiledTarget() {
    return HWY_TARGET;
}
size_t lanes() {
    return simd::lanes();
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include "HwyTargets.h"

namespace kestrel {
namespace {
HWY_EXPORT(vectorExp2);
HWY_EXPORT(compiledTarget);
HWY_EXPORT(lanes);

class SimdMath : public test::EveryTarget {};

TEST_P(SimdMath, DispatchCallsTheChosenTargetsCode) {
    EXPECT_EQ(HWY_DYNAMIC_DISPATCH(compiledTarget)(), GetParam());
}

TEST_P(SimdMath, FastExp2MatchesTheScalarForm) {
    // The scalar form's reduction and polynomial; the vector form fuses the multiply-adds (on
    // the FMA targets), so it is held to exp2 with the stated bound and to the scalar form
    // within a few ulp.
    std::vector<float> xs;
    for (float x = -130.f; x <= 130.f; x += 0.00731f) xs.push_back(x);
    for (float x : {-126.5f, -126.49f, -126.51f, -127.f, -149.f, -200.f, -1e4f, -1e30f, 0.f, -0.5f,
                    0.5f, 126.f, 126.5f, 1e30f})
        xs.push_back(x);
    const std::vector<float> v = HWY_DYNAMIC_DISPATCH(vectorExp2)(xs);
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
    EXPECT_EQ(HWY_DYNAMIC_DISPATCH(vectorExp2)({126.5f, 1e30f})[1], std::exp2(126.f));
    std::printf("simd::fastExp2 on %s (%zu lanes): worst relative error %.2g on [-126, 126]\n",
                hwy::TargetName(GetParam()), HWY_DYNAMIC_DISPATCH(lanes)(), worst);
}

KESTREL_FOR_EVERY_TARGET(SimdMath);

}  // namespace
}  // namespace kestrel
#endif  // HWY_ONCE
