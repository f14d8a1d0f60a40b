#pragma once
// Progress display: a bar with frame count, frames per second and ETA on a terminal; plain
// log lines when standard error is not a terminal (CI, files).
#include <chrono>
#include <cstddef>
#include <cstdint>

namespace kestrel::cli {

class Progress {
public:
    explicit Progress(size_t total);
    void update(size_t done, int64_t frame, double frameMs, bool written);
    /// Erases the bar so a log line can be printed cleanly.
    void clear();
    void finish();

private:
    size_t total_;
    bool tty_;
    bool drawn_ = false;
    std::chrono::steady_clock::time_point start_;
};

}  // namespace kestrel::cli
