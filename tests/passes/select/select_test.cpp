#include <gtest/gtest.h>

#include <map>

#include "SelectPass.h"

using namespace kestrel;

namespace {
// Records what a pass does at compile time.
class FakeResolve final : public ResolveContext {
public:
    std::vector<std::string> bound;
    std::string forwardedFrom, absent, absentWhy;
    std::map<std::string, std::string, std::less<>> why;  ///< unboundReason per input
    bool isBound(std::string_view in) const override {
        return std::find(bound.begin(), bound.end(), in) != bound.end();
    }
    void forward(std::string_view, std::string_view in) override { forwardedFrom = in; }
    void setAbsent(std::string_view out, std::string reason) override {
        absent = out;
        absentWhy = std::move(reason);
    }
    std::string unboundReason(std::string_view in) const override {
        const auto it = why.find(in);
        return it == why.end() ? std::string() : it->second;
    }
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

// An absent output names what each branch lacks, once where both lack the same: the user reads
// which pass to enable, not only that nothing could be produced.
TEST(Select, AbsentOutputNamesWhatEachBranchLacks) {
    SelectPass pass{ParamValues{}};
    FakeResolve same;
    same.why = {{"preferred", "input.depth is absent (enable Z)"},
                {"fallback", "input.depth is absent (enable Z)"}};
    pass.resolve(same);
    EXPECT_EQ(same.absentWhy,
              "neither 'preferred' nor 'fallback' is produced for this scene: input.depth is "
              "absent (enable Z)");
    FakeResolve differ;
    differ.why = {{"preferred", "input.specular is absent"}, {"fallback", "input.depth is absent"}};
    pass.resolve(differ);
    EXPECT_EQ(differ.absentWhy,
              "neither 'preferred' nor 'fallback' is produced for this scene: 'preferred': "
              "input.specular is absent; 'fallback': input.depth is absent");
}
