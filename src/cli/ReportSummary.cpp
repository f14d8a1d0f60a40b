#include "ReportSummary.h"

#include <algorithm>
#include <map>
#include <regex>

namespace kestrel::cli {

namespace {

std::string joined(const std::vector<std::string>& items, const char* sep, size_t most) {
    std::string s;
    for (size_t i = 0; i < items.size() && i < most; ++i) s += (i ? sep : "") + items[i];
    if (items.size() > most) s += sep + std::string("+") + std::to_string(items.size() - most);
    return s;
}

/// One pass's messages as a person reads them: plain mappings ("depth = ViewLayer.Depth.Z")
/// counted, not listed; mappings that carry a reason ("jitteredAlbedo = ViewLayer.DiffCol:
/// anti-aliased render assumed...") grouped by that reason, one line per reason; the rest as
/// they are. A Blender render's loader note was ~1,100 characters of mappings on one line.
std::string passLine(const std::vector<std::string>& messages) {
    static const std::regex plain(R"(^[A-Za-z0-9_]+ = [^:;()]*$)");
    static const std::regex reasoned(R"(^([A-Za-z0-9_]+) = [^:;]*: (.*)$)");
    std::vector<std::string> kept, reasons;
    std::map<std::string, std::vector<std::string>> outputsByReason;
    size_t mapped = 0;
    for (const auto& m : messages) {
        std::smatch g;
        if (std::regex_match(m, plain)) {
            ++mapped;
        } else if (std::regex_match(m, g, reasoned)) {
            if (!outputsByReason.count(g[2])) reasons.push_back(g[2]);
            outputsByReason[g[2]].push_back(g[1]);
        } else {
            kept.push_back(m);
        }
    }
    for (const auto& r : reasons) kept.push_back(joined(outputsByReason[r], ", ", 8) + ": " + r);
    if (mapped)
        kept.push_back(std::to_string(mapped) + " more output" + (mapped > 1 ? "s" : "") +
                       " read as named (-v lists them)");
    return joined(kept, "; ", 64);
}

}  // namespace

std::vector<std::string> groupNotes(const std::vector<std::string>& notes) {
    // message -> passes, and pass -> its messages, both in order of first appearance.
    std::vector<std::string> messages, passes;
    std::map<std::string, std::vector<std::string>> byMessage, byPass;
    for (const auto& n : notes) {
        const auto colon = n.find(": ");
        const std::string pass = colon == std::string::npos ? "" : n.substr(0, colon);
        const std::string message = colon == std::string::npos ? n : n.substr(colon + 2);
        if (!byMessage.count(message)) messages.push_back(message);
        byMessage[message].push_back(pass);
    }
    std::vector<std::string> shared;
    for (const auto& m : messages) {
        const auto& ps = byMessage[m];
        if (ps.size() > 1) {
            shared.push_back(m + " (" + joined(ps, ", ", 3) + ")");
            continue;
        }
        if (!byPass.count(ps[0])) passes.push_back(ps[0]);
        byPass[ps[0]].push_back(m);
    }
    std::vector<std::string> lines;
    for (const auto& p : passes) lines.push_back(p + ": " + passLine(byPass[p]));
    lines.insert(lines.end(), shared.begin(), shared.end());
    return lines;
}

std::string leftOutSummary(const CompileReport& report) {
    const size_t n = report.pruned.size() + report.elided.size();
    if (n == 0) return "";
    // The root causes: the source outputs the scene lacks ("input.diffuse is absent").
    static const std::regex absent(
        R"(([A-Za-z0-9_.]+\.[A-Za-z0-9_]+) is absent)");  // pass names may be instance paths
    std::vector<std::string> causes;
    auto collect = [&](const std::vector<LeftOutPass>& list) {
        for (const auto& p : list)
            for (std::sregex_iterator it(p.reason.begin(), p.reason.end(), absent), end; it != end;
                 ++it)
                if (std::find(causes.begin(), causes.end(), (*it)[1]) == causes.end())
                    causes.push_back((*it)[1]);
    };
    collect(report.pruned);
    collect(report.elided);
    std::string line = "left out " + std::to_string(n) + " passes this scene does not need";
    if (!causes.empty()) line += " (absent: " + joined(causes, ", ", 8) + ")";
    return line + "; -v lists each with its reason";
}

}  // namespace kestrel::cli
