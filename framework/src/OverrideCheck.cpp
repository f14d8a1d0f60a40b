// Overrides that reach nothing the compiled graph runs (docs/graphs.md, "--set and --sweep"):
// a value set on a chain this scene leaves out changes nothing, and a sweep of it gives
// identical rows. The check runs on the graph compiled for the actual input, so it knows each
// left-out pass and the reason the compiler gave.
#include <algorithm>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "kestrel/Compiler.h"

namespace kestrel {

namespace {

using Targets = std::vector<std::pair<std::string, std::string>>;

constexpr const char* kNoOutput = "contributes to no output";

std::string joinNames(const std::vector<std::string>& v) {
    std::string s;
    for (size_t i = 0; i < v.size(); ++i)
        s += (i == 0 ? "" : i + 1 == v.size() ? " or " : ", ") + v[i];
    return s;
}

/// The group instance a flat pass belongs to ("diffuse" for "diffuse.atrous0"), if any.
const GroupInstance* instanceOf(const GraphDesc& g, const std::string& pass) {
    const GroupInstance* best = nullptr;
    for (const auto& i : g.instances)
        if (pass.rfind(i.path + ".", 0) == 0 && (!best || i.path.size() > best->path.size()))
            best = &i;
    return best;
}

class Checker {
public:
    Checker(const CompiledGraph& c, const Registry& r) : compiled_(c), registry_(r) {
        for (const auto& n : c.executionOrder()) live_.insert(n);
        // A pass elided as the identity for its parameters ('*.antilag.enabled=false' makes it
        // so) counts as reached: the override took effect. One elided for a fact of the scene
        // (TAA on a point-sampled render) does not.
        for (const auto& p : c.report().elided)
            if (p.forItsParameters)
                live_.insert(p.pass);
            else
                leftOut_[p.pass] = p.reason;
        for (const auto& p : c.report().pruned) leftOut_[p.pass] = p.reason;
    }

    /// The Diagnostic for one assignment, or nothing when it reaches a live pass.
    std::optional<Diagnostic> check(const std::string& assignment, const std::string& option) {
        GraphDesc copy = compiled_.desc();
        Targets targets;
        try {
            targets = applyOverride(copy, assignment, &registry_, option);
        } catch (const Error&) {
            return std::nullopt;  // refused when it was applied; not this check's to report
        }
        std::vector<std::string> dead;
        for (const auto& [pass, param] : targets) {
            if (live_.count(pass)) return std::nullopt;
            if (leftOut_.count(pass) && std::find(dead.begin(), dead.end(), pass) == dead.end())
                dead.push_back(pass);
        }
        if (dead.empty()) return std::nullopt;  // only passes the command removed (a writer)
        const std::string target = assignment.substr(0, assignment.find('='));
        return Diagnostic{option + " " + assignment, "reaches nothing this render computes: " +
                                                         why(dead) + alternatives(target, targets)};
    }

private:
    /// Why the passes are left out, in the user's terms: the chain's root cause.
    std::string why(const std::vector<std::string>& dead) const {
        const GraphDesc& g = compiled_.desc();
        const GroupInstance* inst = instanceOf(g, dead.front());
        const std::string who = inst ? inst->path + ".*" : dead.front();
        const std::string& reason = leftOut_.at(dead.front());
        // "input.diffuse is absent (layout canonical has no channel diffuse.R/G/B)": the data the
        // chain filters is not in this render.
        static const std::regex absent(R"(([A-Za-z0-9_.]+\.[A-Za-z0-9_]+) is absent( \((.*)\))?)");
        std::smatch m;
        for (const auto& pass : dead)
            if (std::regex_search(leftOut_.at(pass), m, absent))
                return who + " runs only on renders with " + m[1].str() + "; this one has none" +
                       (m[3].matched ? " (" + m[3].str() + ")" : "");
        if (reason == kNoOutput) {
            if (auto unused = unusedBranch(dead)) return who + " " + *unused;
        }
        return who + " is left out: " + reason;
    }

    /// For passes that contribute to no output: the first edge out of the left-out region into
    /// a pass that ignores it (a Select using its other input), said as "runs only when ...",
    /// or into a pass left out for a reason of its own (TAA on a point-sampled render).
    std::optional<std::string> unusedBranch(const std::vector<std::string>& dead) const {
        const GraphDesc& g = compiled_.desc();
        std::set<std::string> seen(dead.begin(), dead.end());
        std::vector<std::string> todo = dead;
        while (!todo.empty()) {
            const std::string pass = todo.back();
            todo.pop_back();
            for (const auto& e : g.edges) {
                if (e.history || e.fromPass != pass) continue;
                auto it = leftOut_.find(e.toPass);
                if (it != leftOut_.end() && it->second == kNoOutput) {
                    if (seen.insert(e.toPass).second) todo.push_back(e.toPass);
                    continue;
                }
                // The reader runs (or is elided, forwarding another input): it ignores this one.
                const std::string used = usedInput(e.toPass);
                if (used.empty() && it != leftOut_.end())  // the reader is left out itself
                    return "feeds only " + e.toPass + ", which is left out: " + it->second;
                if (used.empty() || used == e.toPort) continue;
                std::string feeder;
                for (const auto& f : g.edges)
                    if (f.toPass == e.toPass && f.toPort == used && !f.history)
                        feeder = f.fromPass + "." + f.fromPort;
                std::string comment;  // what the choice means, as the graph's author put it
                for (const auto& n : g.passes)
                    if (n.name == e.toPass && !n.comment.empty())
                        comment = " (" + e.toPass + ": " + n.comment + ")";
                return "runs only when " + e.toPass + "." + used +
                       (feeder.empty() ? "" : " (" + feeder + ")") +
                       " has no data; this render computes it, so " + e.toPass + " uses '" + used +
                       "', not '" + e.toPort + "'" + comment;
            }
        }
        return std::nullopt;
    }

    /// The input a selecting pass forwards for this scene, from its note ("using 'preferred'").
    std::string usedInput(const std::string& pass) const {
        static const std::regex using_(R"(using '([A-Za-z0-9_]+)')");
        std::smatch m;
        auto it = leftOut_.find(pass);
        if (it != leftOut_.end() && std::regex_search(it->second, m, using_)) return m[1];
        for (const auto& n : compiled_.report().notes)
            if (n.rfind(pass + ": ", 0) == 0 && std::regex_search(n, m, using_)) return m[1];
        return {};
    }

    /// "; use diffuse.sigmaL, specular.sigmaL or '*.sigmaL'": the same setting on the live
    /// instances of the same group.
    std::string alternatives(const std::string& target, const Targets& targets) const {
        const GraphDesc& g = compiled_.desc();
        const auto dot = target.rfind('.');
        const std::string param = target.substr(dot + 1);
        const GroupInstance* inst = nullptr;
        for (const auto& i : g.instances)
            if (i.path == target.substr(0, dot)) inst = &i;
        std::string local;  // the pass inside the instance: single.atrous0 -> "atrous0"
        if (!inst && !targets.empty()) {
            inst = instanceOf(g, targets.front().first);
            if (inst && targets.front().first.rfind(inst->path + ".", 0) == 0 &&
                target == targets.front().first + "." + param)
                local = targets.front().first.substr(inst->path.size() + 1);
            else
                inst = nullptr;
        }
        if (!inst || target.find_first_of("*?[") != std::string::npos) return "";
        std::vector<std::string> uses;
        for (const auto& other : g.instances) {
            if (other.group != inst->group || other.path == inst->path) continue;
            bool reaches = false;
            if (local.empty()) {
                if (auto b = other.bindings.find(param); b != other.bindings.end())
                    for (const auto& [pass, p] : b->second) reaches = reaches || live_.count(pass);
            } else {
                reaches = live_.count(other.path + "." + local) > 0;
            }
            if (reaches)
                uses.push_back(other.path + "." + (local.empty() ? "" : local + ".") + param);
        }
        if (uses.empty()) return "";
        uses.push_back("'*." + (local.empty() ? "" : local + ".") + param + "'");
        return "; use " + joinNames(uses);
    }

    const CompiledGraph& compiled_;
    const Registry& registry_;
    std::set<std::string> live_;
    std::map<std::string, std::string> leftOut_;
};

}  // namespace

std::vector<Diagnostic> unusedOverrides(const CompiledGraph& compiled,
                                        const std::vector<std::string>& assignments,
                                        const Registry& registry, const std::string& option) {
    Checker checker(compiled, registry);
    std::vector<Diagnostic> diags;
    for (const auto& a : assignments)
        if (auto d = checker.check(a, option)) diags.push_back(*d);
    return diags;
}

}  // namespace kestrel
