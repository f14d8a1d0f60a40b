// The self-contained HTML page of the bench report: tables, inline SVG plots and PNG crops.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "ReportUtil.h"
#include "eval/BenchReport.h"

namespace kestrel::eval {
namespace {

const char* const kPalette[] = {"#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                                "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"};
const char* colour(size_t i) {
    return kPalette[i % (sizeof kPalette / sizeof *kPalette)];
}

std::string num(double v, const char* f = "%.1f") {
    char b[64];
    std::snprintf(b, sizeof b, f, v);
    return b;
}

// A "nice" tick step (1, 2 or 5 times a power of ten) for about `count` ticks over `range`.
double niceStep(double range, int count) {
    const double raw = range / std::max(1, count);
    const double p = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (raw <= m * p) return m * p;
    return 10 * p;
}

// The plotting area of one chart: linear x, linear or log10 y.
struct Axes {
    double left = 70, top = 20, width = 560, height = 300;
    double xmin = 0, xmax = 1, ymin = 0, ymax = 1;  // y in log10 units when logY
    bool logY = false;
    bool integerX = false;  ///< ticks on whole numbers only (frame numbers)

    double px(double x) const { return left + (x - xmin) / (xmax - xmin) * width; }
    double py(double y) const {
        const double v = logY ? std::log10(std::max(y, 1e-30)) : y;
        return top + (ymax - v) / (ymax - ymin) * height;
    }
    double svgWidth() const { return left + width + 20; }
    double svgHeight() const { return top + height + 50; }

    // Frame, ticks and axis titles.
    void draw(std::ostringstream& os, const std::string& xTitle, const std::string& yTitle,
              bool xTicks = true) const {
        os << "<rect x='" << left << "' y='" << top << "' width='" << width << "' height='"
           << height << "' fill='none' stroke='#444'/>\n";
        if (xTicks) {
            const double step =
                integerX ? std::max(1.0, niceStep(xmax - xmin, 6)) : niceStep(xmax - xmin, 6);
            for (double x = std::ceil(xmin / step) * step; x <= xmax + 1e-9 * step; x += step)
                os << "<line x1='" << px(x) << "' x2='" << px(x) << "' y1='" << top + height
                   << "' y2='" << top + height + 5 << "' stroke='#444'/><text x='" << px(x)
                   << "' y='" << top + height + 18 << "' text-anchor='middle'>"
                   << num(x, step < 1 ? "%.2g" : "%.0f") << "</text>\n";
        }
        if (logY) {
            for (int d = int(std::ceil(ymin - 1e-9)); d <= int(std::floor(ymax + 1e-9)); ++d) {
                const double y = top + (ymax - d) / (ymax - ymin) * height;
                os << "<line x1='" << left << "' x2='" << left + width << "' y1='" << y << "' y2='"
                   << y << "' stroke='#ddd'/><text x='" << left - 6 << "' y='" << y + 4
                   << "' text-anchor='end'>1e" << d << "</text>\n";
            }
        }
        os << "<text x='" << left + width / 2 << "' y='" << top + height + 38
           << "' text-anchor='middle'>" << escapeXml(xTitle) << "</text>\n";
        os << "<text transform='translate(16," << top + height / 2
           << ") rotate(-90)' text-anchor='middle'>" << escapeXml(yTitle) << "</text>\n";
    }
};

// Log10 range covering [lo, hi] on whole decades (at least one decade).
void logRange(double lo, double hi, Axes& a) {
    lo = std::max(lo, 1e-12), hi = std::max(hi, lo);
    a.ymin = std::floor(std::log10(lo));
    a.ymax = std::ceil(std::log10(hi));
    if (a.ymax <= a.ymin) a.ymax = a.ymin + 1;
}

std::string svgOpen(const Axes& a) {
    return "<svg xmlns='http://www.w3.org/2000/svg' width='" + num(a.svgWidth(), "%.0f") +
           "' height='" + num(a.svgHeight(), "%.0f") +
           "' font-family='sans-serif' font-size='11'>\n";
}

// Mean relMSE (log) versus ms per frame; the Pareto front as a dashed staircase.
std::string errorVersusTime(const BenchReport& r, const std::vector<size_t>& pareto) {
    Axes a;
    double tMax = 0, eLo = 1e300, eHi = 0;
    std::vector<double> err;
    for (const BenchRow& row : r.rows) {
        err.push_back(row.mean().relMse);
        tMax = std::max(tMax, row.msPerFrame);
        eLo = std::min(eLo, err.back()), eHi = std::max(eHi, err.back());
    }
    a.xmax = tMax > 0 ? tMax * 1.15 : 1;
    a.logY = true;
    logRange(eLo, eHi, a);
    std::ostringstream os;
    os << svgOpen(a);
    a.draw(os, "ms per frame", "relMSE (log)");
    if (!pareto.empty()) {
        os << "<path d='M" << a.px(r.rows[pareto[0]].msPerFrame) << ',' << a.py(err[pareto[0]]);
        for (size_t k = 1; k < pareto.size(); ++k)
            os << " H" << a.px(r.rows[pareto[k]].msPerFrame) << " V" << a.py(err[pareto[k]]);
        os << "' fill='none' stroke='#222' stroke-dasharray='5,4'><title>Pareto "
              "front</title></path>\n";
    }
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const bool front = std::find(pareto.begin(), pareto.end(), i) != pareto.end();
        const double x = a.px(r.rows[i].msPerFrame), y = a.py(err[i]);
        os << "<circle cx='" << x << "' cy='" << y << "' r='" << (front ? 6 : 4.5) << "' fill='"
           << colour(i) << "'" << (front ? " stroke='#000' stroke-width='2'" : "") << "><title>"
           << escapeXml(r.rows[i].name) << ": " << num(err[i], "%.4g") << " relMSE, "
           << num(r.rows[i].msPerFrame, "%.2f") << " ms</title></circle>\n";
        os << "<text x='" << x + 8 << "' y='" << y - 6 << "'>" << escapeXml(r.rows[i].name)
           << "</text>\n";
    }
    os << "</svg>\n";
    return os.str();
}

// relMSE (log) per frame, one line per setting.
std::string errorPerFrame(const BenchReport& r) {
    Axes a;
    size_t n = 0;
    double eLo = 1e300, eHi = 0;
    for (const BenchRow& row : r.rows) {
        n = std::max(n, row.errors.size());
        for (const FrameMetrics& e : row.errors)
            eLo = std::min(eLo, e.relMse), eHi = std::max(eHi, e.relMse);
    }
    auto frameOf = [&](size_t i) { return i < r.frames.size() ? double(r.frames[i]) : double(i); };
    a.xmin = n ? frameOf(0) : 0;
    a.xmax = n > 1 ? frameOf(n - 1) : a.xmin + 1;
    if (a.xmax <= a.xmin) a.xmax = a.xmin + 1;
    a.logY = true;
    a.integerX = true;
    logRange(eLo, eHi, a);
    std::ostringstream os;
    os << svgOpen(a);
    a.draw(os, "frame", "relMSE (log)");
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const BenchRow& row = r.rows[i];
        os << "<polyline fill='none' stroke-width='2' stroke='" << colour(i) << "' points='";
        for (size_t f = 0; f < row.errors.size(); ++f)
            os << a.px(frameOf(f)) << ',' << a.py(row.errors[f].relMse) << ' ';
        os << "'><title>" << escapeXml(row.name) << "</title></polyline>\n";
        os << "<text x='" << a.left + 8 << "' y='" << a.top + 14 + 14 * double(i) << "' fill='"
           << colour(i) << "'>" << escapeXml(row.name) << "</text>\n";
    }
    os << "</svg>\n";
    return os.str();
}

// Per-pass ms as horizontal stacked bars, one bar per setting.
std::string passBreakdown(const BenchReport& r) {
    std::vector<std::string> passes;  // first-seen order
    double tMax = 0;
    for (const BenchRow& row : r.rows) {
        double total = 0;
        for (const auto& [pass, ms] : row.passMs) {
            if (std::find(passes.begin(), passes.end(), pass) == passes.end())
                passes.push_back(pass);
            total += std::max(ms, 0.0);
        }
        tMax = std::max(tMax, total);
    }
    Axes a;
    a.left = 170;
    a.width = 460;
    a.height = std::max(60.0, 28.0 * double(r.rows.size()));
    a.xmax = tMax > 0 ? tMax * 1.05 : 1;
    std::ostringstream os;
    Axes tall = a;
    tall.height += 16 + 18.0 * double((passes.size() + 3) / 4);  // room for the legend
    os << svgOpen(tall);
    a.draw(os, "ms per frame", "");
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const double y = a.top + 28.0 * double(i) + 5;
        os << "<text x='" << a.left - 6 << "' y='" << y + 13 << "' text-anchor='end'>"
           << escapeXml(r.rows[i].name) << "</text>\n";
        double t = 0;
        for (const auto& [pass, ms] : r.rows[i].passMs) {
            const size_t k = size_t(std::find(passes.begin(), passes.end(), pass) - passes.begin());
            const double w = std::max(ms, 0.0);
            os << "<rect x='" << a.px(t) << "' y='" << y << "' width='" << a.px(t + w) - a.px(t)
               << "' height='18' fill='" << colour(k) << "'><title>" << escapeXml(pass) << ": "
               << num(ms, "%.3f") << " ms</title></rect>\n";
            t += w;
        }
    }
    for (size_t k = 0; k < passes.size(); ++k) {
        const double x = a.left + 115.0 * double(k % 4),
                     y = a.top + a.height + 64 + 18.0 * double(k / 4);
        os << "<rect x='" << x << "' y='" << y - 9 << "' width='10' height='10' fill='" << colour(k)
           << "'/><text x='" << x + 14 << "' y='" << y << "'>" << escapeXml(passes[k])
           << "</text>\n";
    }
    os << "</svg>\n";
    return os.str();
}

std::string cropFigure(const ImageView& img, ToneMap t, const std::string& label) {
    if (!img.valid()) return "";
    const int scale = img.width() < 200 ? 2 : 1;
    return "<figure><img alt='" + escapeXml(label) + "' width='" +
           std::to_string(img.width() * scale) +
           "' style='image-rendering:pixelated' "
           "src='data:image/png;base64," +
           base64(encodePng(img, t)) + "'><figcaption>" + escapeXml(label) +
           "</figcaption></figure>\n";
}

}  // namespace

std::string benchHtml(const BenchReport& r, const std::vector<size_t>& pareto) {
    std::ostringstream os;
    os << "<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>" << escapeXml(r.title)
       << "</title>\n<style>body{font-family:sans-serif;margin:2em;color:#222}"
          "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px}"
          "td.n{text-align:right}figure{display:inline-block;margin:0 8px 8px 0}"
          "figcaption{font-size:12px;text-align:center}</style></head><body>\n";
    os << "<h1>" << escapeXml(r.title) << "</h1>\n<p>" << r.frames.size()
       << " frames. PSNR, SSIM and temporal instability on " << toneMapName(r.toneMap)
       << "-tone-mapped values; bold rows are on the Pareto front of (ms per frame, relMSE).</p>\n";
    os << "<table><tr><th>setting</th><th>relMSE</th><th>PSNR dB</th><th>SSIM</th>"
          "<th>temporal</th><th>ms/frame</th></tr>\n";
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const FrameMetrics m = r.rows[i].mean();
        const bool front = std::find(pareto.begin(), pareto.end(), i) != pareto.end();
        os << "<tr" << (front ? " style='font-weight:bold'" : "") << "><td>"
           << escapeXml(r.rows[i].name) << "</td><td class='n'>" << num(m.relMse, "%.6g")
           << "</td><td class='n'>" << num(m.psnr, "%.2f") << "</td><td class='n'>"
           << num(m.ssim, "%.4f") << "</td><td class='n'>"
           << (m.temporal ? num(*m.temporal, "%.6f") : "-") << "</td><td class='n'>"
           << num(r.rows[i].msPerFrame, "%.2f") << "</td></tr>\n";
    }
    os << "</table>\n<h2>Error versus time</h2>\n" << errorVersusTime(r, pareto);
    os << "<h2>Error per frame</h2>\n" << errorPerFrame(r);
    os << "<h2>Time per pass</h2>\n" << passBreakdown(r);
    bool anyCrop = r.noisyCrop.extent().pixels() > 0 || r.referenceCrop.extent().pixels() > 0;
    bool intermediates = false;
    for (const BenchRow& row : r.rows) {
        anyCrop = anyCrop || row.crop.extent().pixels() > 0;
        intermediates = intermediates || !row.intermediateCrops.empty();
    }
    if (anyCrop) {
        os << "<h2>Crops</h2>\n<p>" << escapeXml(r.cropNote) << "</p>\n<div>\n";
        os << cropFigure(r.noisyCrop, r.toneMap, "noisy input");
        if (intermediates) {  // one line per setting: what led to its output, then the output
            os << cropFigure(r.referenceCrop, r.toneMap, "reference") << "</div>\n";
            for (const BenchRow& row : r.rows) {
                os << "<div>\n";
                for (const auto& [name, crop] : row.intermediateCrops)
                    os << cropFigure(crop, r.toneMap, row.name + ": " + name);
                os << cropFigure(row.crop, r.toneMap, row.name) << "</div>\n";
            }
        } else {
            for (const BenchRow& row : r.rows) os << cropFigure(row.crop, r.toneMap, row.name);
            os << cropFigure(r.referenceCrop, r.toneMap, "reference") << "</div>\n";
        }
    }
    os << "</body></html>\n";
    return os.str();
}

}  // namespace kestrel::eval
