#include <gtest/gtest.h>

#include "SelectPass.h"

using namespace kestrel;

namespace {
// Records what a pass does at compile time.
class FakeResolve final : public ResolveContext {
public:
    std::vector<std::string> bound;
    std::string forwardedFrom, absent;
    bool isBound(std::string_view in) const override {
        return std::find(bound.begin(), bound.end(), in) != bound.end();
    }
    void forward(std::string_view, std::string_view in) override { forwardedFrom = in; }
    void setAbsent(std::string_view out, std::string) override { absent = out; }
    void note(std::string) override {}
    int64_t firstFrame() const override { return 0; }
    std::string_view passName() const override { return "select"; }
};
}  // namespace

TEST(Select, PrefersPreferredThenFallbackElseAbsent) {
    SelectPass pass{ParamValues{}};
    FakeResolve both;
    both.bound = {"preferred", "fallback"};
    pass.resolve(both);
    EXPECT_EQ(both.forwardedFrom, "preferred");

    FakeResolve onlyFallback;
    onlyFallback.bound = {"fallback"};
    pass.resolve(onlyFallback);
    EXPECT_EQ(onlyFallback.forwardedFrom, "fallback");

    FakeResolve none;
    pass.resolve(none);
    EXPECT_EQ(none.forwardedFrom, "");
    EXPECT_EQ(none.absent, "output");
}
