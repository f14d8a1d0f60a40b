#pragma once
// `kestrel compare`: metrics of an output sequence against a reference sequence, frame by frame
// and averaged, as an aligned text table or JSON. The CLI command is a thin wrapper.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "eval/Metrics.h"

namespace kestrel::eval {

struct CompareOptions {
    std::string outPattern;  ///< FramePattern syntax (frame.####.exr, %04d) or a single file
    std::string refPattern;
    /// Frames to compare, in order. Empty: every frame whose output file exists (or, when only
    /// the reference pattern has a frame token, every reference frame); patterns without a frame
    /// token compare one pair of files.
    std::vector<int64_t> frames;
    ToneMap toneMap = ToneMap::Reinhard;
    std::string outLayer, refLayer;  ///< RGB layer to read (empty: automatic, see ExrRgb.h)
};

struct FrameComparison {
    std::optional<int64_t> frame;  ///< absent when neither pattern has a frame token
    std::string outPath, refPath;
    FrameMetrics metrics;
};

struct CompareResult {
    std::string outPattern, refPattern;
    ToneMap toneMap = ToneMap::Reinhard;
    std::vector<FrameComparison> frames;
    /// Means over frames: relMSE, PSNR (mean of per-frame dB) and SSIM over all frames; temporal
    /// over the frames that have it (absent with a single frame). Non-finite counts are sums.
    FrameMetrics mean;
};

/// Reads each frame pair and computes its metrics; temporal instability compares each frame with
/// the previous one in the list (with --frames 1-9x2, frame 3 with frame 1). Holds at most two
/// frames in memory. Throws kestrel::Error for a bad pattern, no frames found, and (FrameError)
/// a missing or unreadable file or a size mismatch, naming the file.
CompareResult compareSequences(const CompareOptions& options);

/// An aligned table: one row per frame, then the mean; a note when inputs had NaN/Inf.
std::string formatTable(const CompareResult& result);

/// {"output", "reference", "toneMap", "frames": [{"frame", "output", "reference", "relMse",
///  "psnr", "ssim", "temporal" (null on the first frame), "nonFiniteOutput",
///  "nonFiniteReference"}...], "mean": {... "frames": N}}.
nlohmann::json toJson(const CompareResult& result);

}  // namespace kestrel::eval
