#include "Progress.h"

#include <unistd.h>

#include <cstdio>
#include <string>

#include "kestrel/Log.h"

namespace kestrel::cli {

Progress::Progress(size_t total)
    : total_(total), tty_(isatty(fileno(stderr)) != 0), start_(std::chrono::steady_clock::now()) {}

void Progress::update(size_t done, int64_t frame, double frameMs, bool written) {
    double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    double fps = elapsed > 0 ? double(done) / elapsed : 0;
    double eta = fps > 0 ? double(total_ - done) / fps : 0;
    if (!tty_) {
        spdlog::info("frame {} ({}/{}){}: {:.1f} ms", frame, done, total_,
                     written ? "" : " warm-up", frameMs);
        return;
    }
    const int width = 30;
    int filled = total_ ? int(double(done) / double(total_) * width) : width;
    std::string bar(size_t(filled), '#');
    bar.resize(size_t(width), '.');
    std::fprintf(stderr, "\r[%s] %zu/%zu frames  %.1f fps  ETA %.0f s  (frame %lld)\033[K",
                 bar.c_str(), done, total_, fps, eta, static_cast<long long>(frame));
    std::fflush(stderr);
    drawn_ = true;
}

void Progress::clear() {
    if (tty_ && drawn_) {
        std::fprintf(stderr, "\r\033[K");
        drawn_ = false;
    }
}

void Progress::finish() {
    if (tty_ && drawn_) std::fprintf(stderr, "\n");
    drawn_ = false;
}

}  // namespace kestrel::cli
