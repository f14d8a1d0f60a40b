#include "kestrel/Parallel.h"

#include <algorithm>
#include <exception>

namespace kestrel {

Parallel::Parallel(int threads) {
    if (threads <= 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
    for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { workerLoop(); });
}

Parallel::~Parallel() {
    {
        std::lock_guard lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    for (auto& t : workers_) t.join();
}

void Parallel::runChunks() {
    const auto& fn = *job_;
    for (;;) {
        int b = jobBegin_ + next_.fetch_add(1, std::memory_order_relaxed) * jobGrain_;
        if (b >= jobEnd_) break;
        fn(b, std::min(jobEnd_, b + jobGrain_));
    }
}

void Parallel::workerLoop() {
    uint64_t seen = 0;
    for (;;) {
        {
            std::unique_lock lock(mutex_);
            wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
            if (stop_) return;
            seen = generation_;
        }
        runChunks();
        {
            std::lock_guard lock(mutex_);
            if (--active_ == 0) done_.notify_one();
        }
    }
}

void Parallel::forRange(int begin, int end, const std::function<void(int, int)>& fn, int grain) {
    if (end <= begin) return;
    int n = end - begin;
    // The chunk size depends only on the range, never on the thread count, so chunk
    // boundaries (and any per-chunk arithmetic) are identical for every --threads value.
    if (grain <= 0) grain = std::max(1, std::min(16, n / 64));
    if (workers_.empty() || n <= grain) {
        for (int b = begin; b < end; b += grain) fn(b, std::min(end, b + grain));
        return;
    }
    // An exception escaping a worker thread would terminate the process: catch the first one,
    // skip the remaining chunks, and rethrow it on the calling thread once all workers are idle.
    std::exception_ptr error;
    std::mutex errorMutex;
    std::atomic<bool> failed{false};
    const std::function<void(int, int)> guarded = [&](int b, int e) {
        if (failed.load(std::memory_order_relaxed)) return;
        try {
            fn(b, e);
        } catch (...) {
            std::lock_guard lock(errorMutex);
            if (!error) error = std::current_exception();
            failed.store(true, std::memory_order_relaxed);
        }
    };
    {
        std::lock_guard lock(mutex_);
        job_ = &guarded;
        jobBegin_ = begin;
        jobEnd_ = end;
        jobGrain_ = grain;
        next_.store(0);
        active_ = int(workers_.size());
        ++generation_;
    }
    wake_.notify_all();
    runChunks();
    {
        std::unique_lock lock(mutex_);
        done_.wait(lock, [&] { return active_ == 0; });
        job_ = nullptr;
    }
    if (error) std::rethrow_exception(error);
}

}  // namespace kestrel
