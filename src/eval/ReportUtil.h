#pragma once
// Private helpers of the bench report writer.
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace kestrel::eval {

struct BenchReport;
/// The self-contained HTML page (BenchHtml.cpp); `pareto` as returned by paretoFront.
std::string benchHtml(const BenchReport& report, const std::vector<size_t>& pareto);

struct BenchRow;
/// "A (1.00-1.20 ms) and B (...) tie on time ...": a timingTies pair in words.
std::string tieText(const BenchRow& fast, const BenchRow& accurate);

std::string base64(const std::vector<unsigned char>& bytes);

/// Escapes &, <, >, " for HTML/SVG text and attributes.
inline std::string escapeXml(std::string_view s) {
    std::string o;
    for (char c : s) {
        switch (c) {
            case '&':
                o += "&amp;";
                break;
            case '<':
                o += "&lt;";
                break;
            case '>':
                o += "&gt;";
                break;
            case '"':
                o += "&quot;";
                break;
            default:
                o += c;
        }
    }
    return o;
}

/// Quotes a CSV field when it holds a comma, quote or newline (RFC 4180).
inline std::string csvField(std::string_view s) {
    if (s.find_first_of(",\"\n") == std::string_view::npos) return std::string(s);
    std::string o = "\"";
    for (char c : s) o += c == '"' ? std::string("\"\"") : std::string(1, c);
    return o + "\"";
}

}  // namespace kestrel::eval
