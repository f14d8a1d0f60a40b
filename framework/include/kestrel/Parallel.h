#pragma once
// The one way passes use threads: a fixed pool and a parallel-for over index ranges. Ranges are
// cut into chunks that do not depend on the thread count, and every index is processed by
// exactly one call, so a pass whose per-index work is independent gives identical results for
// every thread count.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace kestrel {

class Parallel {
public:
    /// threads <= 0: one per hardware thread.
    explicit Parallel(int threads = 0);
    ~Parallel();
    Parallel(const Parallel&) = delete;
    Parallel& operator=(const Parallel&) = delete;

    int threadCount() const { return int(workers_.size()) + 1; }

    /// Calls fn(b, e) for consecutive chunks [b, e) covering [begin, end). The calling thread
    /// takes part. `grain` is the chunk size (0: automatic, fixed for a given range length).
    void forRange(int begin, int end, const std::function<void(int, int)>& fn, int grain = 0);

private:
    void workerLoop();
    void runChunks();

    std::vector<std::thread> workers_;
    std::mutex mutex_;
    std::condition_variable wake_, done_;
    const std::function<void(int, int)>* job_ = nullptr;
    int jobBegin_ = 0, jobEnd_ = 0, jobGrain_ = 1;
    std::atomic<int> next_{0};
    int active_ = 0;
    uint64_t generation_ = 0;
    bool stop_ = false;
};

}  // namespace kestrel
