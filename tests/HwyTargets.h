#pragma once
// Runs a parameterised test once per SIMD target: every target compiled into the build (the
// kernels' hwy/foreach_target.h list, which this header's translation unit shares through the
// build's compile definitions) that this CPU can run. The fixture restricts Highway's run-time
// dispatch to the parameter's target for the test's duration, so HWY_DYNAMIC_DISPATCH inside a
// pass calls that target's kernel.
#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <cstdint>
#include <string>

namespace kestrel::test {

class EveryTarget : public ::testing::TestWithParam<int64_t> {
protected:
    void SetUp() override {
        hwy::SetSupportedTargetsForTest(GetParam());
        ASSERT_EQ(hwy::SupportedTargets(), GetParam()) << "dispatch not restricted to the target";
    }
    void TearDown() override { hwy::SetSupportedTargetsForTest(0); }
};

inline std::string targetName(const ::testing::TestParamInfo<int64_t>& info) {
    return hwy::TargetName(info.param);
}

}  // namespace kestrel::test

/// Instantiates the TEST_P tests of `fixture` (derived from EveryTarget) for every target.
#define KESTREL_FOR_EVERY_TARGET(fixture)                                              \
    INSTANTIATE_TEST_SUITE_P(Target, fixture,                                          \
                             ::testing::ValuesIn(hwy::SupportedAndGeneratedTargets()), \
                             kestrel::test::targetName)
