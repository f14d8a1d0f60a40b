// Bench report: means, Pareto front, Markdown and CSV tables; the HTML page is in BenchHtml.cpp.
#include "eval/BenchReport.h"

#include <kestrel/Error.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "ReportUtil.h"

namespace kestrel::eval {
namespace {

std::string fmt(const char* f, double v) {
    char b[64];
    std::snprintf(b, sizeof b, f, v);
    return b;
}

std::string temporalText(const std::optional<double>& t) {
    return t ? fmt("%.6f", *t) : std::string();
}

void writeFile(const std::filesystem::path& path, const std::string& text) {
    // Written to a temporary name, then renamed: no half-written report is left behind.
    std::filesystem::path tmp = path;
    tmp += ".tmp";
    {
        std::ofstream f(tmp, std::ios::binary);
        f << text;
        if (!f.flush()) throw Error("cannot write '" + path.string() + "'");
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw Error("cannot write '" + path.string() + "': " + ec.message());
}

std::string markdown(const BenchReport& r, const std::vector<size_t>& pareto) {
    std::ostringstream os;
    os << "# " << r.title << "\n\n";
    os << "Frames: " << r.frames.size() << "; PSNR, SSIM and temporal instability on "
       << toneMapName(r.toneMap) << "-tone-mapped values; * = on the Pareto front of "
       << "(ms per frame, relMSE).\n\n";
    os << "| setting | relMSE | PSNR dB | SSIM | temporal | speckles/Mpx | ms/frame | ms range "
          "over rounds | Pareto |\n";
    os << "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | :---: |\n";
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const BenchRow& row = r.rows[i];
        const FrameMetrics m = row.mean();
        const bool front = std::find(pareto.begin(), pareto.end(), i) != pareto.end();
        os << "| " << row.name << " | " << fmt("%.6g", m.relMse) << " | " << fmt("%.2f", m.psnr)
           << " | " << fmt("%.4f", m.ssim) << " | " << (m.temporal ? fmt("%.6f", *m.temporal) : "-")
           << " | " << fmt("%.0f", m.speckles) << " | " << fmt("%.2f", row.msPerFrame) << " | "
           << (row.msMax > 0 ? fmt("%.2f", row.msMin) + "-" + fmt("%.2f", row.msMax) : "-") << " | "
           << (front ? "*" : "") << " |\n";
    }
    for (const auto& [i, j] : timingTies(r.rows, pareto))
        os << "\nTie: " << tieText(r.rows[i], r.rows[j]) << ".\n";
    os << "\n## Time per pass (ms per frame)\n\n| setting | pass | ms |\n| --- | --- | ---: |\n";
    for (const BenchRow& row : r.rows)
        for (const auto& [pass, ms] : row.passMs)
            os << "| " << row.name << " | " << pass << " | " << fmt("%.3f", ms) << " |\n";
    return os.str();
}

}  // namespace

FrameMetrics BenchRow::mean() const {
    FrameMetrics m;
    if (errors.empty()) return m;
    double t = 0;
    size_t nt = 0;
    for (const FrameMetrics& e : errors) {
        m.relMse += e.relMse;
        m.psnr += e.psnr;
        m.ssim += e.ssim;
        m.speckles += e.speckles;
        if (e.temporal) t += *e.temporal, ++nt;
        m.nonFiniteOutput += e.nonFiniteOutput;
        m.nonFiniteReference += e.nonFiniteReference;
    }
    const double n = double(errors.size());
    m.relMse /= n, m.psnr /= n, m.ssim /= n, m.speckles /= n;
    if (nt) m.temporal = t / double(nt);
    return m;
}

std::vector<size_t> paretoFront(const std::vector<BenchRow>& rows) {
    std::vector<double> err(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) err[i] = rows[i].mean().relMse;
    std::vector<size_t> front;
    for (size_t i = 0; i < rows.size(); ++i) {
        bool dominated = false;
        for (size_t j = 0; j < rows.size() && !dominated; ++j) {
            const double ti = rows[i].msPerFrame, tj = rows[j].msPerFrame;
            dominated = j != i && tj <= ti && err[j] <= err[i] && (tj < ti || err[j] < err[i]);
        }
        if (!dominated) front.push_back(i);
    }
    std::stable_sort(front.begin(), front.end(),
                     [&](size_t a, size_t b) { return rows[a].msPerFrame < rows[b].msPerFrame; });
    return front;
}

std::vector<std::pair<size_t, size_t>> timingTies(const std::vector<BenchRow>& rows,
                                                  const std::vector<size_t>& pareto) {
    auto lo = [&](size_t i) { return rows[i].msMax > 0 ? rows[i].msMin : rows[i].msPerFrame; };
    auto hi = [&](size_t i) { return rows[i].msMax > 0 ? rows[i].msMax : rows[i].msPerFrame; };
    std::vector<std::pair<size_t, size_t>> ties;
    for (size_t a = 0; a < pareto.size(); ++a)
        for (size_t b = a + 1; b < pareto.size(); ++b) {
            const size_t i = pareto[a], j = pareto[b];  // by ms: i no slower than j
            if (rows[i].inputOnly || rows[j].inputOnly) continue;
            if (hi(i) >= lo(j)) ties.push_back({i, j});
        }
    return ties;
}

std::string tieText(const BenchRow& fast, const BenchRow& accurate) {
    auto range = [](const BenchRow& r) {
        return r.msMax > 0 ? fmt("%.2f", r.msMin) + "-" + fmt("%.2f", r.msMax) + " ms"
                           : fmt("%.2f ms", r.msPerFrame);
    };
    return fast.name + " (" + range(fast) + ") and " + accurate.name + " (" + range(accurate) +
           ") tie on time within the spread over the rounds: " + accurate.name +
           ", the lower error, is the pick";
}

BenchFiles writeBenchReport(const BenchReport& r, const std::filesystem::path& dir) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw Error("cannot create '" + dir.string() + "': " + ec.message());
    const std::vector<size_t> pareto = paretoFront(r.rows);
    BenchFiles files{dir / "bench.md", dir / "bench.csv", dir / "bench_frames.csv",
                     dir / "bench_passes.csv", dir / "bench.html"};

    std::ostringstream csv, frames, passes;
    csv << "setting,relMse,psnr,ssim,temporal,msPerFrame,pareto,nonFiniteOutput,speckles,msMin,"
           "msMax\n";
    frames << "setting,frame,relMse,psnr,ssim,temporal,nonFiniteOutput,speckles\n";
    passes << "setting,pass,ms\n";
    for (size_t i = 0; i < r.rows.size(); ++i) {
        const BenchRow& row = r.rows[i];
        const FrameMetrics m = row.mean();
        const bool front = std::find(pareto.begin(), pareto.end(), i) != pareto.end();
        csv << csvField(row.name) << ',' << fmt("%.9g", m.relMse) << ',' << fmt("%.6g", m.psnr)
            << ',' << fmt("%.6g", m.ssim) << ',' << temporalText(m.temporal) << ','
            << fmt("%.6g", row.msPerFrame) << ',' << (front ? 1 : 0) << ',' << m.nonFiniteOutput
            << ',' << fmt("%.6g", m.speckles) << ',' << fmt("%.6g", row.msMin) << ','
            << fmt("%.6g", row.msMax) << '\n';
        for (size_t f = 0; f < row.errors.size(); ++f) {
            const FrameMetrics& e = row.errors[f];
            frames << csvField(row.name) << ','
                   << (f < r.frames.size() ? std::to_string(r.frames[f]) : std::to_string(f)) << ','
                   << fmt("%.9g", e.relMse) << ',' << fmt("%.6g", e.psnr) << ','
                   << fmt("%.6g", e.ssim) << ',' << temporalText(e.temporal) << ','
                   << e.nonFiniteOutput << ',' << fmt("%.6g", e.speckles) << '\n';
        }
        for (const auto& [pass, ms] : row.passMs)
            passes << csvField(row.name) << ',' << csvField(pass) << ',' << fmt("%.6g", ms) << '\n';
    }
    writeFile(files.markdown, markdown(r, pareto));
    writeFile(files.csv, csv.str());
    writeFile(files.framesCsv, frames.str());
    writeFile(files.passesCsv, passes.str());
    writeFile(files.html, benchHtml(r, pareto));
    return files;
}

}  // namespace kestrel::eval
