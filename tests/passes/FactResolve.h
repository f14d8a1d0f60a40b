#pragma once
// A ResolveContext for unit tests of passes that read scene facts at compile time
// (ResolveContext::fact): every input counts as bound and the facts are the ones given.
#include <kestrel/Pass.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace svgftest {

class FactResolve final : public kestrel::ResolveContext {
public:
    FactResolve() = default;
    /// One fact.
    FactResolve(std::string key, std::string value) { facts_[std::move(key)] = std::move(value); }
    bool isBound(std::string_view) const override { return true; }
    void forward(std::string_view, std::string_view in) override { forwardedFrom = in; }
    void setAbsent(std::string_view, std::string) override {}
    void note(std::string n) override { notes.push_back(std::move(n)); }
    std::optional<std::string> fact(std::string_view key) const override {
        const auto it = facts_.find(key);
        if (it == facts_.end()) return std::nullopt;
        return it->second;
    }
    int64_t firstFrame() const override { return 0; }
    std::string_view passName() const override { return "pass"; }
    std::vector<std::string> notes;
    std::string forwardedFrom;  ///< the input the last forward() named

private:
    std::map<std::string, std::string, std::less<>> facts_;
};

}  // namespace svgftest
