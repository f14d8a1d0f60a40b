#include <gtest/gtest.h>

#include <string>

#include "../FactResolve.h"
#include "../SvgfTestImages.h"
#include "MixPass.h"

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

namespace {
std::string forwardedAt(double weight) {
    auto h = PassHarness::make<MixPass>({1, 1}, {{"weight", weight}});
    FactResolve rc;
    h.pass().resolve(rc);
    return rc.forwardedFrom;
}
}  // namespace

TEST(Mix, BlendsPerChannel) {
    Image a = constant(2, 1, Format::Float3, 1.f), b = constant(2, 1, Format::Float3, 3.f);
    b.at(1, 1, 0) = -1.f;
    auto h = PassHarness::make<MixPass>({2, 1}, {{"weight", 0.25}});
    h.bind("a", a);
    h.bind("b", b);
    h.run();
    EXPECT_FLOAT_EQ(h.out("color").at(0, 0, 0), 1.5f);
    EXPECT_FLOAT_EQ(h.out("color").at(2, 1, 0), 1.5f);
    EXPECT_FLOAT_EQ(h.out("color").at(1, 1, 0), 0.5f);  // 1 + 0.25 * (-1 - 1)
}

// Weight 0 or 1 is one of the inputs: forwarded at compile time, so the pass never runs.
TEST(Mix, WeightZeroOrOneForwardsAnInput) {
    EXPECT_EQ(forwardedAt(0.0), "a");
    EXPECT_EQ(forwardedAt(1.0), "b");
    EXPECT_EQ(forwardedAt(0.5), "");
}

TEST(Mix, NonFiniteInputsGiveFiniteOutputs) {
    Image a = constant(3, 1, Format::Float3, 1.f), b = constant(3, 1, Format::Float3, 2.f);
    a.at(0, 0, 0) = NAN;
    b.at(1, 1, 0) = INFINITY;
    b.at(2, 2, 0) = -INFINITY;
    auto h = PassHarness::make<MixPass>({3, 1}, {{"weight", 0.5}});
    h.bind("a", a);
    h.bind("b", b);
    h.run();
    EXPECT_TRUE(allFinite(h.out("color")));
    // Non-finite values count as 0: 0 + 0.5 * (2 - 0), 1 + 0.5 * (0 - 1).
    EXPECT_FLOAT_EQ(h.out("color").at(0, 0, 0), 1.f);
    EXPECT_FLOAT_EQ(h.out("color").at(1, 1, 0), 0.5f);
    EXPECT_FLOAT_EQ(h.out("color").at(2, 2, 0), 0.5f);
}
