#pragma once
// The report of `kestrel bench`: error against a reference versus run time for several graphs or
// parameter settings, so that a user can pick a pipeline (metrics: docs/design.md section 7).
//
// writeBenchReport(report, dir) writes
//   bench.md            summary and per-pass tables (Markdown)
//   bench.csv           one line per setting: mean metrics, ms per frame, on the Pareto front,
//                       the spread of ms per frame over the rounds (msMin, msMax)
//   bench_frames.csv    one line per setting and frame: metrics of that frame
//   bench_passes.csv    one line per setting and pass: ms (of the setting's median frame)
//   bench.html          self-contained: the tables, inline SVG plots (mean relMSE, log scale,
//                       versus ms per frame with the Pareto front, the spread as whiskers, the
//                       input row off scale, labels that never overlap; relMSE per frame;
//                       per-pass time as stacked bars by chain and stage) and crops as PNG data
//                       URIs: where the error is worst when the rows' frames are given (with a
//                       difference image and an A/B flip), else the rows' `crop`s; a script
//                       that records in <body data-label-check> whether any two labels overlap
#include <kestrel/Image.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "eval/Metrics.h"

namespace kestrel::eval {

/// One graph or parameter setting.
struct BenchRow {
    std::string name;                  ///< e.g. "svgf", "svgf alpha=0.1"
    std::vector<FrameMetrics> errors;  ///< per frame, in BenchReport::frames order
    double msPerFrame = 0;             ///< median over frames after a warm-up
    /// The spread of ms per frame: the lowest and highest of the rounds' medians (kestrel bench
    /// --rounds); both 0 when unknown.
    double msMin = 0, msMax = 0;
    std::vector<std::pair<std::string, double>> passMs;  ///< per pass, median ms, in run order
    Image crop;  ///< optional: a crop of one output frame, linear RGB (empty: none)
    /// Optional: the same crop of intermediate resources ("pass.port", linear RGB), shown beside
    /// the output crop (kestrel bench --crop-dump).
    std::vector<std::pair<std::string, Image>> intermediateCrops;
    /// Optional: the whole output frame the crops come from (linear RGB), and the same frame of
    /// the intermediates; given with BenchReport::referenceFrame, the report cuts its crops
    /// where the settings' error is worst instead of showing `crop`.
    Image frame;
    std::vector<std::pair<std::string, Image>> intermediateFrames;
    /// The unfiltered input (the error of doing nothing): plotted off the error axis, so the
    /// settings being compared spread over it instead of sitting on its bottom edge.
    bool inputOnly = false;

    /// Means over frames (temporal over the frames that have it).
    FrameMetrics mean() const;
};

struct BenchReport {
    std::string title = "kestrel bench";
    std::vector<int64_t> frames;  ///< frame numbers of the per-frame errors
    std::vector<BenchRow> rows;
    ToneMap toneMap = ToneMap::Reinhard;  ///< of the metrics and of the crops' PNGs
    std::string cropNote;                 ///< e.g. "frame 8, x 100-227, y 40-167"
    Image noisyCrop, referenceCrop;       ///< optional, linear RGB, same crop as the rows'
    /// Optional, with the rows' `frame`s: the whole frame of the crops, its number, and how
    /// many crops of what side (at most a third of the frame's short side, at least 16) to cut
    /// where the settings err most.
    Image noisyFrame, referenceFrame;
    int64_t cropFrameNumber = 0;
    int cropCount = 3, cropSize = 96;
};

/// A window of a frame.
struct CropRect {
    int x0 = 0, y0 = 0, w = 0, h = 0;
};
/// Up to `count` windows of side `size` (clipped to the frame) where the outputs' mean relative
/// squared error against the reference, sum of (out - ref)^2 / (ref^2 + 0.01), is highest: worst
/// first, none overlapping another. The windows are searched on a grid of size/4 pixels.
std::vector<CropRect> worstRegions(const std::vector<ImageView>& outputs, const ImageView& ref,
                                   int size, int count);

/// Pairs (i, j) of Pareto-front rows, i faster than j by the median, whose times overlap within
/// their round-to-round spread (msMin-msMax): between them the pick is by error only (j).
std::vector<std::pair<size_t, size_t>> timingTies(const std::vector<BenchRow>& rows,
                                                  const std::vector<size_t>& pareto);

/// Indices of the rows on the Pareto front of (msPerFrame, mean relMSE), both minimised: no other
/// row is at least as good in both and strictly better in one. Sorted by ms per frame.
std::vector<size_t> paretoFront(const std::vector<BenchRow>& rows);

/// An 8-bit RGB PNG (in memory) of a linear RGB image through the tone map.
std::vector<unsigned char> encodePng(const ImageView& rgb, ToneMap toneMap);

struct BenchFiles {
    std::filesystem::path markdown, csv, framesCsv, passesCsv, html;
};
/// Writes the report files into `dir` (created if needed). Throws kestrel::Error naming the file
/// that could not be written.
BenchFiles writeBenchReport(const BenchReport& report, const std::filesystem::path& dir);

}  // namespace kestrel::eval
