// The self-contained HTML page of the bench report: tables, inline SVG plots and PNG crops.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
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
// The palette, then distinct hues (golden-angle steps): no two stages share a colour.
std::string stageColour(size_t k) {
    const size_t n = sizeof kPalette / sizeof *kPalette;
    if (k < n) return kPalette[k];
    return "hsl(" + std::to_string((k - n) * 137 % 360) + ",45%,55%)";
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

    // Grid lines and labels at 1, 2 and 5 (or 1..9) times the decades when the range is under
    // two decades, so a tight range still has ticks; at whole decades otherwise.
    void drawLogTicks(std::ostringstream& os) const {
        std::vector<double> mantissas = {1};
        if (ymax - ymin < 2) mantissas = {1, 2, 5};
        if (ymax - ymin < 0.5) mantissas = {1, 2, 3, 4, 5, 6, 7, 8, 9};
        for (int d = int(std::floor(ymin)); d <= int(std::ceil(ymax)); ++d)
            for (double m : mantissas) {
                const double v = std::log10(m) + d;
                if (v < ymin - 1e-9 || v > ymax + 1e-9) continue;
                const double y = top + (ymax - v) / (ymax - ymin) * height;
                os << "<line x1='" << left << "' x2='" << left + width << "' y1='" << y << "' y2='"
                   << y << "' stroke='#ddd'/><text x='" << left - 6 << "' y='" << y + 4
                   << "' text-anchor='end'>"
                   << (m == 1 ? "1e" + std::to_string(d) : num(m * std::pow(10.0, d), "%.3g"))
                   << "</text>\n";
            }
    }

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
        if (logY) drawLogTicks(os);
        os << "<text x='" << left + width / 2 << "' y='" << top + height + 38
           << "' text-anchor='middle'>" << escapeXml(xTitle) << "</text>\n";
        os << "<text transform='translate(16," << top + height / 2
           << ") rotate(-90)' text-anchor='middle'>" << escapeXml(yTitle) << "</text>\n";
    }
};

// Log10 range covering [lo, hi]: on whole decades when they span two or more, else the data's
// own range with a margin (settings of one sweep often differ by a few percent: whole decades
// would squeeze them onto a few pixels).
void logRange(double lo, double hi, Axes& a) {
    lo = std::max(lo, 1e-12), hi = std::max(hi, lo);
    a.ymin = std::floor(std::log10(lo));
    a.ymax = std::ceil(std::log10(hi));
    if (a.ymax - a.ymin >= 2) return;
    const double l = std::log10(lo), h = std::log10(hi), margin = std::max(0.1 * (h - l), 0.02);
    a.ymin = l - margin, a.ymax = h + margin;
}

std::string svgOpen(const Axes& a) {
    return "<svg xmlns='http://www.w3.org/2000/svg' width='" + num(a.svgWidth(), "%.0f") +
           "' height='" + num(a.svgHeight(), "%.0f") +
           "' font-family='sans-serif' font-size='11'>\n";
}

// A label's box in SVG units; text width estimated from the character count (11 px sans-serif
// averages under 6.5 px a character; the browser test checks the real boxes).
struct Box {
    double x0, y0, x1, y1;
    bool overlaps(const Box& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
    bool inside(const Box& o) const { return x0 >= o.x0 && x1 <= o.x1 && y0 >= o.y0 && y1 <= o.y1; }
};
double textWidth(const std::string& s) {
    return 6.5 * double(s.size()) + 2;
}

// Places labels next to their points without overlapping each other or any point: tries eight
// positions around the point; a label that fits nowhere is replaced by its number (also tried
// around the point), and the number is explained in a legend under the plot.
class LabelPlacer {
public:
    explicit LabelPlacer(Box area) : area_(area) {}
    void addObstacle(Box b) { taken_.push_back(b); }

    /// The text's anchor (x, baseline y) at one of the free positions, or nothing.
    std::optional<std::pair<double, double>> place(double px, double py, const std::string& text) {
        const double w = textWidth(text), h = 13, d = 7;
        const std::pair<double, double> offsets[] = {
            {d, -d - h}, {d, d},           {-d - w, -d - h}, {-d - w, d},
            {d, -h / 2}, {-d - w, -h / 2}, {-w / 2, -d - h}, {-w / 2, d}};
        for (const auto& [dx, dy] : offsets) {
            const Box b{px + dx, py + dy, px + dx + w, py + dy + h};
            if (!b.inside(area_)) continue;
            if (std::any_of(taken_.begin(), taken_.end(),
                            [&](const Box& t) { return t.overlaps(b); }))
                continue;
            taken_.push_back(b);
            return std::make_pair(b.x0 + 1, b.y1 - 3);
        }
        return std::nullopt;
    }

private:
    Box area_;
    std::vector<Box> taken_;
};

std::string psnrText(const BenchRow& row) {
    return num(row.mean().psnr, "%.1f") + " dB";
}

// Mean relMSE (log) versus ms per frame; the Pareto front as a dashed staircase. The axes cover
// the filtered settings only: the unfiltered input, usually orders of magnitude worse, is an
// arrow at the top edge saying where it is.
std::string errorVersusTime(const BenchReport& r, const std::vector<size_t>& pareto) {
    std::vector<size_t> onAxis, offScale;
    for (size_t i = 0; i < r.rows.size(); ++i)
        (r.rows[i].inputOnly ? offScale : onAxis).push_back(i);
    if (onAxis.empty()) std::swap(onAxis, offScale);  // nothing else: the input is the plot
    Axes a;
    a.top = 40;  // room for the off-scale arrows and their labels
    double tMax = 0, eLo = 1e300, eHi = 0;
    std::vector<double> err;
    for (const BenchRow& row : r.rows) err.push_back(row.mean().relMse);
    for (size_t i : onAxis) {
        tMax = std::max({tMax, r.rows[i].msPerFrame, r.rows[i].msMax});
        eLo = std::min(eLo, err[i]), eHi = std::max(eHi, err[i]);
    }
    a.xmax = tMax > 0 ? tMax * 1.15 : 1;
    a.logY = true;
    logRange(eLo, eHi, a);
    LabelPlacer labels({a.left, 0, a.left + a.width, a.top + a.height});
    std::ostringstream os, marks, legend;
    std::vector<std::string> legendLines;
    auto label = [&](double x, double y, const std::string& text, size_t i) {
        if (auto at = labels.place(x, y, text)) {
            marks << "<text class='lbl' x='" << at->first << "' y='" << at->second << "'>"
                  << escapeXml(text) << "</text>\n";
            return;
        }
        const std::string n = std::to_string(legendLines.size() + 1);
        legendLines.push_back(n + ": " + text);
        if (auto at = labels.place(x, y, n))
            marks << "<text class='lbl' x='" << at->first << "' y='" << at->second << "' fill='"
                  << colour(i) << "'>" << n << "</text>\n";
    };
    std::vector<size_t> front;  // the staircase joins the front's on-axis rows only
    for (size_t i : pareto)
        if (std::find(onAxis.begin(), onAxis.end(), i) != onAxis.end()) front.push_back(i);
    if (!front.empty()) {
        marks << "<path d='M" << a.px(r.rows[front[0]].msPerFrame) << ',' << a.py(err[front[0]]);
        for (size_t k = 1; k < front.size(); ++k)
            marks << " H" << a.px(r.rows[front[k]].msPerFrame) << " V" << a.py(err[front[k]]);
        marks << "' fill='none' stroke='#222' stroke-dasharray='5,4'><title>Pareto "
                 "front</title></path>\n";
    }
    for (size_t i : onAxis)
        labels.addObstacle({a.px(r.rows[i].msPerFrame) - 6, a.py(err[i]) - 6,
                            a.px(r.rows[i].msPerFrame) + 6, a.py(err[i]) + 6});
    for (size_t i : offScale) {  // an up arrow on the top edge
        const double x = std::min(a.px(r.rows[i].msPerFrame), a.left + a.width - 6);
        labels.addObstacle({x - 6, a.top - 14, x + 6, a.top});
        marks << "<path d='M" << x << ',' << a.top - 14 << " l-6,10 h12 z' fill='" << colour(i)
              << "'><title>" << escapeXml(r.rows[i].name) << ": " << num(err[i], "%.4g")
              << " relMSE, above this axis</title></path>\n";
    }
    for (size_t i : offScale)
        label(std::min(a.px(r.rows[i].msPerFrame), a.left + a.width - 6), a.top - 8,
              r.rows[i].name + ": " + psnrText(r.rows[i]) + ", off scale", i);
    for (size_t i : onAxis) {  // the spread over the rounds: a whisker from min to max
        const BenchRow& row = r.rows[i];
        if (row.msMax <= row.msMin) continue;
        const double y = a.py(err[i]), x0 = a.px(row.msMin), x1 = a.px(row.msMax);
        marks << "<path d='M" << x0 << ',' << y - 4 << " v8 M" << x0 << ',' << y << " H" << x1
              << " M" << x1 << ',' << y - 4 << " v8' stroke='" << colour(i)
              << "' stroke-width='1.5' fill='none'><title>" << escapeXml(row.name) << ": "
              << num(row.msMin, "%.2f") << "-" << num(row.msMax, "%.2f")
              << " ms over the rounds</title></path>\n";
        labels.addObstacle({x0, y - 4, x1, y + 4});
    }
    for (size_t i : onAxis) {
        const bool onFront = std::find(pareto.begin(), pareto.end(), i) != pareto.end();
        const double x = a.px(r.rows[i].msPerFrame), y = a.py(err[i]);
        marks << "<circle cx='" << x << "' cy='" << y << "' r='" << (onFront ? 6 : 4.5)
              << "' fill='" << colour(i) << "'"
              << (onFront ? " stroke='#000' stroke-width='2'" : "") << "><title>"
              << escapeXml(r.rows[i].name) << ": " << num(err[i], "%.4g") << " relMSE, "
              << num(r.rows[i].msPerFrame, "%.2f") << " ms</title></circle>\n";
        label(x, y, r.rows[i].name, i);
    }
    Axes tall = a;
    tall.height += 16.0 * double(legendLines.size()) + (legendLines.empty() ? 0 : 4);
    os << svgOpen(tall);
    a.draw(os, "ms per frame", "relMSE (log)");
    os << marks.str();
    for (size_t k = 0; k < legendLines.size(); ++k)
        os << "<text class='lbl' x='" << a.left << "' y='"
           << a.top + a.height + 62 + 16.0 * double(k) << "'>" << escapeXml(legendLines[k])
           << "</text>\n";
    os << "</svg>\n";
    return os.str();
}

// relMSE (log) per frame, one line per setting. As in errorVersusTime the axis fits the filtered
// settings; the unfiltered input is named in the legend as off scale instead of drawn.
std::string errorPerFrame(const BenchReport& r) {
    Axes a;
    size_t n = 0;
    double eLo = 1e300, eHi = 0;
    const bool anyFiltered = std::any_of(r.rows.begin(), r.rows.end(),
                                         [](const BenchRow& row) { return !row.inputOnly; });
    auto offScale = [&](const BenchRow& row) { return anyFiltered && row.inputOnly; };
    for (const BenchRow& row : r.rows) {
        n = std::max(n, row.errors.size());
        if (offScale(row)) continue;
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
    // The legend right of the plot, not over its lines.
    auto legendText = [&](const BenchRow& row) {
        return offScale(row) ? row.name + ": " + psnrText(row) + ", off scale" : row.name;
    };
    double legendWidth = 0;
    for (const BenchRow& row : r.rows)
        legendWidth = std::max(legendWidth, textWidth(legendText(row)));
    Axes page = a;
    page.width += 12 + legendWidth;
    page.height = std::max(a.height, 14.0 * double(r.rows.size()) + 10);
    const double lx = a.left + a.width + 12;
    std::ostringstream os;
    os << svgOpen(page);
    a.draw(os, "frame", "relMSE (log)");
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const BenchRow& row = r.rows[i];
        const double ly = a.top + 10 + 14 * double(i);
        if (offScale(row)) {
            os << "<text x='" << lx << "' y='" << ly << "' fill='" << colour(i) << "'>"
               << escapeXml(legendText(row)) << "</text>\n";
            continue;
        }
        os << "<polyline fill='none' stroke-width='2' stroke='" << colour(i) << "' points='";
        for (size_t f = 0; f < row.errors.size(); ++f)
            os << a.px(frameOf(f)) << ',' << a.py(row.errors[f].relMse) << ' ';
        os << "'><title>" << escapeXml(row.name) << "</title></polyline>\n";
        os << "<text x='" << lx << "' y='" << ly << "' fill='" << colour(i) << "'>"
           << escapeXml(row.name) << "</text>\n";
    }
    os << "</svg>\n";
    return os.str();
}

// A pass's chain (its group instance: "diffuse", "specular", "single"; "" outside any group) and
// stage (its name in the group, iteration numbers dropped: atrous0..4 are one stage "atrous").
std::pair<std::string, std::string> chainAndStage(const std::string& pass) {
    const size_t dot = pass.rfind('.');
    std::string chain = dot == std::string::npos ? "" : pass.substr(0, dot);
    std::string stage = dot == std::string::npos ? pass : pass.substr(dot + 1);
    while (stage.size() > 1 && std::isdigit(static_cast<unsigned char>(stage.back())))
        stage.pop_back();
    return {chain, stage};
}

// Per-pass ms as horizontal stacked bars, one bar per setting, passes summed by chain and stage:
// one colour per stage (a handful, not one per pass), chains split by a white gap and named in
// the tooltip. The bars are the table's ms per frame: the CLI takes every pass's time from the
// setting's median frame.
std::string passBreakdown(const BenchReport& r) {
    struct Segment {
        std::string chain, stage;
        double ms = 0;
        int passes = 0;
    };
    std::vector<std::string> stages;  // first-seen order: the legend
    std::vector<std::vector<Segment>> bars;
    double tMax = 0;
    size_t longest = 0;
    for (const BenchRow& row : r.rows) {
        std::vector<Segment> bar;
        double total = 0;
        for (const auto& [pass, ms] : row.passMs) {
            auto [chain, stage] = chainAndStage(pass);
            if (std::find(stages.begin(), stages.end(), stage) == stages.end())
                stages.push_back(stage);
            auto it = std::find_if(bar.begin(), bar.end(), [&](const Segment& s) {
                return s.chain == chain && s.stage == stage;
            });
            if (it == bar.end()) it = bar.insert(bar.end(), Segment{chain, stage});
            it->ms += std::max(ms, 0.0), ++it->passes;
            total += std::max(ms, 0.0);
        }
        std::vector<std::string> chains;  // first-seen order: a chain's stages side by side
        for (const Segment& s : bar)
            if (std::find(chains.begin(), chains.end(), s.chain) == chains.end())
                chains.push_back(s.chain);
        auto rank = [&](const Segment& s) {
            return std::find(chains.begin(), chains.end(), s.chain) - chains.begin();
        };
        std::stable_sort(bar.begin(), bar.end(),
                         [&](const Segment& a, const Segment& b) { return rank(a) < rank(b); });
        bars.push_back(std::move(bar));
        tMax = std::max(tMax, total);
        longest = std::max(longest, row.name.size());
    }
    Axes a;
    a.left = std::max(120.0, textWidth(std::string(longest, 'x')) + 12);
    a.width = 460;
    a.height = std::max(60.0, 28.0 * double(r.rows.size()));
    a.xmax = tMax > 0 ? tMax * 1.2 : 1;  // room for the totals
    const int columns = 4;
    const double column = 140;
    Axes tall = a;
    tall.height += 16 + 18.0 * double((stages.size() + columns - 1) / columns);
    tall.width = std::max(a.width, column * columns);
    std::ostringstream os;
    os << svgOpen(tall);
    a.draw(os, "ms per frame", "");
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const double y = a.top + 28.0 * double(i) + 5;
        os << "<text x='" << a.left - 6 << "' y='" << y + 13 << "' text-anchor='end'>"
           << escapeXml(r.rows[i].name) << "</text>\n";
        double t = 0;
        for (const Segment& s : bars[i]) {
            const size_t k =
                size_t(std::find(stages.begin(), stages.end(), s.stage) - stages.begin());
            os << "<rect x='" << a.px(t) << "' y='" << y << "' width='" << a.px(t + s.ms) - a.px(t)
               << "' height='18' fill='" << stageColour(k)
               << "' stroke='#fff' stroke-width='0.5'><title>"
               << escapeXml(s.chain.empty() ? s.stage : s.chain + " \u00b7 " + s.stage) << " ("
               << s.passes << (s.passes == 1 ? " pass" : " passes") << "): " << num(s.ms, "%.3f")
               << " ms</title></rect>\n";
            t += s.ms;
        }
        os << "<text class='total' x='" << a.px(t) + 4 << "' y='" << y + 13 << "'>"
           << num(t, "%.2f") << "</text>\n";
    }
    for (size_t k = 0; k < stages.size(); ++k) {
        const double x = a.left + column * double(k % columns),
                     y = a.top + a.height + 64 + 18.0 * double(k / columns);
        os << "<rect x='" << x << "' y='" << y - 9 << "' width='10' height='10' fill='"
           << stageColour(k) << "'/><text x='" << x + 14 << "' y='" << y << "'>"
           << escapeXml(stages[k]) << "</text>\n";
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

// Measures, as the page's last script (layout is then complete for the plots), every text of
// every plot and writes into <body data-label-check> "ok N" (N texts, no two overlapping) or the
// overlapping pairs; once loaded, data-images "decoded/all" and data-flip "ok" when the first
// A/B picture flips and back on two clicks: what tests/cli/report_browser_test.sh reads from
// headless chromium's --dump-dom.
const char* const kLabelCheck = R"(<script>
(() => {
  const bad = [];
  let n = 0;
  for (const svg of document.querySelectorAll('svg')) {
    const boxes = [...svg.querySelectorAll('text')].filter(t => t.textContent.trim())
      .map(t => [t.textContent, t.getBoundingClientRect()]);
    n += boxes.length;
    boxes.forEach(([ta, a], i) => boxes.slice(i + 1).forEach(([tb, b]) => {
      if (a.left < b.right - 0.5 && b.left < a.right - 0.5 && a.top < b.bottom - 0.5 &&
          b.top < a.bottom - 0.5) bad.push(ta + ' / ' + tb);
    }));
  }
  document.body.dataset.labelCheck = bad.length ? 'overlap: ' + bad.join('; ') : 'ok ' + n;
})();
addEventListener('load', () => {
  const imgs = [...document.images];
  document.body.dataset.images =
    imgs.filter(i => i.complete && i.naturalWidth > 0).length + '/' + imgs.length;
  const flip = document.querySelector('img.flip');  // two clicks: flipped and back
  if (flip) {
    const a = flip.src;
    flip.click();
    const flipped = flip.src !== a;
    flip.click();
    document.body.dataset.flip = flipped && flip.src === a ? 'ok' : 'broken';
  }
});
</script>
)";

Image cut(const ImageView& img, const CropRect& r) {
    Image c(r.w, r.h, Format::Float3);
    for (int ch = 0; ch < 3; ++ch)
        for (int y = 0; y < r.h; ++y)
            for (int x = 0; x < r.w; ++x)
                c.at(ch, x, y) = img.at(std::min(ch, img.channels() - 1), r.x0 + x, r.y0 + y);
    return c;
}

// |a - b| per channel, brightened so that the 99th percentile of the largest channel is white:
// a firefly does not turn the rest black. The gain goes in the caption.
Image difference(const ImageView& a, const ImageView& b, double& gain) {
    Image d(a.width(), a.height(), Format::Float3);
    std::vector<float> peak;
    for (int y = 0; y < a.height(); ++y)
        for (int x = 0; x < a.width(); ++x) {
            float m = 0;
            for (int c = 0; c < 3; ++c) {
                const float v = std::fabs(a.at(c, x, y) - b.at(c, x, y));
                d.at(c, x, y) = std::isfinite(v) ? v : 0.0f;
                m = std::max(m, d.at(c, x, y));
            }
            peak.push_back(m);
        }
    std::sort(peak.begin(), peak.end());
    const float p99 = peak.empty() ? 0.0f : peak[peak.size() * 99 / 100];
    gain = p99 > 0 ? 1.0 / p99 : 1.0;
    for (int c = 0; c < 3; ++c)
        for (int y = 0; y < d.height(); ++y)
            for (int x = 0; x < d.width(); ++x) d.at(c, x, y) *= float(gain);
    return d;
}

std::string dataUri(const ImageView& img, ToneMap t) {
    return "data:image/png;base64," + base64(encodePng(img, t));
}

// The best setting's crop that flips to the reference's on a click (the script kFlip).
std::string flipFigure(const ImageView& a, const ImageView& b, ToneMap t, const std::string& an) {
    const int scale = a.width() < 200 ? 2 : 1;
    return "<figure class='ab'><img class='flip' alt='A/B: " + escapeXml(an) +
           " | reference' width='" + std::to_string(a.width() * scale) +
           "' style='image-rendering:pixelated;cursor:pointer' src='" + dataUri(a, t) +
           "' data-other='" + dataUri(b, t) + "' data-names='" + escapeXml(an) +
           "|reference'><figcaption>A/B: " + escapeXml(an) +
           " (click: reference)</figcaption></figure>\n";
}

bool hasFrame(const BenchRow& row, const BenchReport& r) {
    return !row.inputOnly && row.frame.extent().pixels() > 0 &&
           row.frame.extent() == r.referenceFrame.extent();
}

// The row with the lowest mean error among those with a frame, not the input: the A/B flip's
// and the difference image's subject.
const BenchRow* bestRow(const BenchReport& r) {
    const BenchRow* best = nullptr;
    for (const BenchRow& row : r.rows)
        if (hasFrame(row, r) && (!best || row.mean().relMse < best->mean().relMse)) best = &row;
    return best;
}

// Crops where the settings err most (worstRegions over their frames), each with the input, every
// setting (and its intermediates), the reference, the best setting's difference to it and an A/B
// flip between the two.
std::string worstCrops(const BenchReport& r) {
    const BenchRow* best = bestRow(r);
    if (!best) return "";
    std::vector<ImageView> outs;
    for (const BenchRow& row : r.rows)
        if (hasFrame(row, r)) outs.push_back(row.frame.view());
    // A third of the frame's short side at most: several crops even on a small frame.
    const int side = std::min(r.referenceFrame.width(), r.referenceFrame.height());
    const int size = std::min(r.cropSize, std::max(16, side / 3));
    const std::vector<CropRect> regions =
        worstRegions(outs, r.referenceFrame.view(), size, r.cropCount);
    std::ostringstream os;
    os << "<h2>Crops</h2>\n<p>Frame " << r.cropFrameNumber << ": the " << regions.size()
       << " windows where the settings' error (relative squared error, averaged over the "
          "settings) is worst, worst first. The difference image is the best setting's ("
       << escapeXml(best->name) << "); click its A/B picture to flip to the reference.</p>\n";
    for (size_t k = 0; k < regions.size(); ++k) {
        const CropRect& c = regions[k];
        os << "<h3>Crop " << k + 1 << ": x " << c.x0 << "-" << c.x0 + c.w - 1 << ", y " << c.y0
           << "-" << c.y0 + c.h - 1 << "</h3>\n<div>\n";
        if (r.noisyFrame.extent() == r.referenceFrame.extent())  // both given
            os << cropFigure(cut(r.noisyFrame, c), r.toneMap, "noisy input");
        for (const BenchRow& row : r.rows) {
            if (!hasFrame(row, r)) continue;
            for (const auto& [name, frame] : row.intermediateFrames)
                os << cropFigure(cut(frame, c), r.toneMap, row.name + ": " + name);
            os << cropFigure(cut(row.frame, c), r.toneMap, row.name);
        }
        const Image ref = cut(r.referenceFrame, c), out = cut(best->frame, c);
        double gain = 1;
        const Image diff = difference(out, ref, gain);
        os << cropFigure(ref, r.toneMap, "reference")
           << cropFigure(diff, ToneMap::Clamp,
                         "|" + best->name + " - reference| x" + num(gain, "%.3g"))
           << flipFigure(out, ref, r.toneMap, best->name) << "</div>\n";
    }
    return os.str();
}

// Flips an A/B picture between its two images (and names) on a click.
const char* const kFlip = R"(<script>
for (const img of document.querySelectorAll('img.flip')) img.addEventListener('click', () => {
  [img.src, img.dataset.other] = [img.dataset.other, img.src];
  const [a, b] = img.dataset.names.split('|');
  img.dataset.names = b + '|' + a;
  img.nextElementSibling.textContent = 'A/B: ' + b + ' (click: ' + a + ')';
});
</script>
)";

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
          "<th>temporal</th><th>ms/frame</th><th>ms over rounds</th></tr>\n";
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const FrameMetrics m = r.rows[i].mean();
        const bool front = std::find(pareto.begin(), pareto.end(), i) != pareto.end();
        os << "<tr" << (front ? " style='font-weight:bold'" : "") << "><td>"
           << escapeXml(r.rows[i].name) << "</td><td class='n'>" << num(m.relMse, "%.6g")
           << "</td><td class='n'>" << num(m.psnr, "%.2f") << "</td><td class='n'>"
           << num(m.ssim, "%.4f") << "</td><td class='n'>"
           << (m.temporal ? num(*m.temporal, "%.6f") : "-") << "</td><td class='n'>"
           << num(r.rows[i].msPerFrame, "%.2f") << "</td><td class='n'>"
           << (r.rows[i].msMax > 0
                   ? num(r.rows[i].msMin, "%.2f") + "-" + num(r.rows[i].msMax, "%.2f")
                   : "-")
           << "</td></tr>\n";
    }
    os << "</table>\n<h2>Error versus time</h2>\n" << errorVersusTime(r, pareto);
    os << "<p>Whiskers: the lowest and highest of the rounds' median ms per frame.</p>\n";
    for (const auto& [i, j] : timingTies(r.rows, pareto))
        os << "<p class='tie'>Tie: " << escapeXml(tieText(r.rows[i], r.rows[j])) << ".</p>\n";
    os << "<h2>Error per frame</h2>\n" << errorPerFrame(r);
    os << "<h2>Time per pass</h2>\n" << passBreakdown(r);
    bool anyCrop = r.noisyCrop.extent().pixels() > 0 || r.referenceCrop.extent().pixels() > 0;
    bool intermediates = false;
    for (const BenchRow& row : r.rows) {
        anyCrop = anyCrop || row.crop.extent().pixels() > 0;
        intermediates = intermediates || !row.intermediateCrops.empty();
    }
    if (r.referenceFrame.extent().pixels() > 0 && bestRow(r)) {
        os << worstCrops(r) << kFlip;
    } else if (anyCrop) {
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
    os << kLabelCheck << "</body></html>\n";
    return os.str();
}

}  // namespace kestrel::eval
