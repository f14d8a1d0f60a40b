#include "eval/Compare.h"

#include <kestrel/Error.h>
#include <kestrel/FramePattern.h>

#include <cstdio>
#include <sstream>

#include "eval/ExrRgb.h"

namespace kestrel::eval {
namespace {

struct Job {
    std::optional<int64_t> frame;
    std::string out, ref;
};

std::vector<Job> planJobs(const CompareOptions& o) {
    const FramePattern outP(o.outPattern), refP(o.refPattern);
    std::vector<Job> jobs;
    if (!outP.hasFrameToken() && !refP.hasFrameToken()) {
        if (!o.frames.empty())
            throw Error("--frames needs a frame token (#, @ or %d) in '" + o.outPattern + "' or '" +
                        o.refPattern + "'");
        jobs.push_back({std::nullopt, o.outPattern, o.refPattern});
        return jobs;
    }
    std::vector<int64_t> frames = o.frames;
    if (frames.empty()) {
        const FramePattern& source = outP.hasFrameToken() ? outP : refP;
        frames = source.findFrames();
        if (frames.empty())
            throw Error("no files match '" + source.pattern() + "' (use --frames to name frames)");
    }
    for (int64_t f : frames) jobs.push_back({f, outP.expand(f), refP.expand(f)});
    return jobs;
}

std::string frameLabel(const std::optional<int64_t>& f) {
    return f ? "frame " + std::to_string(*f) + ": " : std::string();
}

}  // namespace

CompareResult compareSequences(const CompareOptions& options) {
    CompareResult result;
    result.outPattern = options.outPattern;
    result.refPattern = options.refPattern;
    result.toneMap = options.toneMap;
    const std::vector<Job> jobs = planJobs(options);

    FrameImages previous, current;
    double sumRel = 0, sumPsnr = 0, sumSsim = 0, sumTemporal = 0, sumSpeckles = 0;
    size_t temporalCount = 0;
    for (const Job& job : jobs) {
        Image out = readExrRgb(job.out, options.outLayer);
        Image ref = readExrRgb(job.ref, options.refLayer);
        if (out.extent() != ref.extent())
            throw FrameError(frameLabel(job.frame) + "'" + job.out + "' is " +
                             std::to_string(out.width()) + "x" + std::to_string(out.height()) +
                             " but '" + job.ref + "' is " + std::to_string(ref.width()) + "x" +
                             std::to_string(ref.height()));
        const bool hasPrevious = !result.frames.empty();
        if (hasPrevious && previous.outDisplay.extent() != out.extent())
            throw FrameError(frameLabel(job.frame) + "'" + job.out +
                             "' differs in size from the previous frame");
        FrameMetrics m =
            compareImages(out, ref, options.toneMap, hasPrevious ? &previous : nullptr, &current);
        std::swap(previous, current);
        sumRel += m.relMse;
        sumPsnr += m.psnr;
        sumSsim += m.ssim;
        sumSpeckles += m.speckles;
        if (m.temporal) sumTemporal += *m.temporal, ++temporalCount;
        result.mean.nonFiniteOutput += m.nonFiniteOutput;
        result.mean.nonFiniteReference += m.nonFiniteReference;
        result.frames.push_back({job.frame, job.out, job.ref, m});
    }
    const double n = double(result.frames.size());
    result.mean.relMse = sumRel / n;
    result.mean.psnr = sumPsnr / n;
    result.mean.ssim = sumSsim / n;
    result.mean.speckles = sumSpeckles / n;
    if (temporalCount) result.mean.temporal = sumTemporal / double(temporalCount);
    return result;
}

std::string formatTable(const CompareResult& r) {
    bool anyNonFinite = r.mean.nonFiniteOutput || r.mean.nonFiniteReference;
    std::ostringstream os;
    os << "output:    " << r.outPattern << "\nreference: " << r.refPattern
       << "\ntone map:  " << toneMapName(r.toneMap)
       << " (PSNR, SSIM, temporal); speckles per megapixel (isolated dark pixels, Metrics.h)\n\n";
    char line[256];
    std::snprintf(line, sizeof line, "%8s  %12s  %8s  %7s  %10s  %9s", "frame", "relMSE", "PSNR dB",
                  "SSIM", "temporal", "speckles");
    os << line << (anyNonFinite ? "  NaN/Inf out  NaN/Inf ref" : "") << "\n";
    auto row = [&](const std::string& label, const FrameMetrics& m) {
        char t[32] = "-";
        if (m.temporal) std::snprintf(t, sizeof t, "%.6f", *m.temporal);
        std::snprintf(line, sizeof line, "%8s  %12.6g  %8.2f  %7.4f  %10s  %9.0f", label.c_str(),
                      m.relMse, m.psnr, m.ssim, t, m.speckles);
        os << line;
        if (anyNonFinite) {
            std::snprintf(line, sizeof line, "  %11zu  %11zu", m.nonFiniteOutput,
                          m.nonFiniteReference);
            os << line;
        }
        os << "\n";
    };
    for (const FrameComparison& f : r.frames)
        row(f.frame ? std::to_string(*f.frame) : "-", f.metrics);
    if (r.frames.size() > 1) row("mean", r.mean);
    if (anyNonFinite)
        os << "\nnote: pixels with NaN/Inf were counted and replaced before the metrics "
              "(NaN -> 0, Inf -> +-FLT_MAX)\n";
    return os.str();
}

nlohmann::json toJson(const CompareResult& r) {
    auto metrics = [](const FrameMetrics& m) {
        nlohmann::json j;
        j["relMse"] = m.relMse;
        j["psnr"] = m.psnr;
        j["ssim"] = m.ssim;
        j["speckles"] = m.speckles;
        j["temporal"] = m.temporal ? nlohmann::json(*m.temporal) : nlohmann::json(nullptr);
        j["nonFiniteOutput"] = m.nonFiniteOutput;
        j["nonFiniteReference"] = m.nonFiniteReference;
        return j;
    };
    nlohmann::json j;
    j["output"] = r.outPattern;
    j["reference"] = r.refPattern;
    j["toneMap"] = std::string(toneMapName(r.toneMap));
    j["frames"] = nlohmann::json::array();
    for (const FrameComparison& f : r.frames) {
        nlohmann::json fj = metrics(f.metrics);
        fj["frame"] = f.frame ? nlohmann::json(*f.frame) : nlohmann::json(nullptr);
        fj["output"] = f.outPath;
        fj["reference"] = f.refPath;
        j["frames"].push_back(std::move(fj));
    }
    j["mean"] = metrics(r.mean);
    j["mean"]["frames"] = r.frames.size();
    return j;
}

}  // namespace kestrel::eval
