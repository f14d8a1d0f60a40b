#pragma once
// Frame-numbered file names, with oiiotool's grammar:
//   frame.####.exr  a run of N '#' is N digits, zero padded; a single '#' means 4 digits
//   frame.@@@.exr   each '@' is one digit (zero padded to the run's length)
//   frame.%04d.exr  printf style, zero padded to the given width; %d is unpadded
// At most one frame token per pattern; a pattern without one names a single file used for every
// frame. Frame lists ("--frames") read: 7 | 1-100 | 1-100x2 | 3,4,10-20x2 (negative numbers
// allowed).
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace kestrel {

class FramePattern {
public:
    /// Throws Error naming the pattern on bad syntax (two tokens, "%5x", "%-4d", ...).
    explicit FramePattern(std::string_view pattern);

    const std::string& pattern() const { return pattern_; }
    bool hasFrameToken() const { return hasToken_; }
    /// Minimum digit count (0: unpadded %d).
    int padding() const { return width_; }

    /// The file name of `frame` (frame 7 in frame.####.exr -> frame.0007.exr; -3 ->
    /// frame.-003.exr).
    std::string expand(int64_t frame) const;
    /// The frame number encoded in `path` if it matches the pattern exactly (with the pattern's
    /// padding: frame.0007.exr matches ####, frame.7.exr does not).
    std::optional<int64_t> match(std::string_view path) const;
    /// Frame numbers whose files exist on disk, sorted. Empty without a frame token or when
    /// the directory is missing. The token must be in the file name, not in a directory.
    std::vector<int64_t> findFrames() const;

private:
    std::string pattern_;
    std::string prefix_, suffix_;  // around the token, '%%' already unescaped
    bool hasToken_ = false;
    int width_ = 0;
};

/// expand() without keeping the parsed pattern.
std::string expandFramePattern(std::string_view pattern, int64_t frame);
/// findFrames() without keeping the parsed pattern.
std::vector<int64_t> findFrames(std::string_view pattern);

/// Parses a frame list: "7", "1-100", "1-100x2", "3,4,10-20x2", "-5--1". Frames in the order
/// given (duplicates kept). Throws Error quoting the text and the bad item.
std::vector<int64_t> parseFrameRange(std::string_view text);

}  // namespace kestrel
