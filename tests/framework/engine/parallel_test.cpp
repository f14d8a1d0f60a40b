// kestrel::Parallel: full coverage of index ranges, and thread-count-independent results.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <vector>

#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

TEST(Parallel, ForRangeCoversEveryIndexExactlyOnce) {
    for (int threads : {1, 2, 3}) {
        Parallel par(threads);
        ASSERT_EQ(par.threadCount(), threads);
        for (int begin : {0, 5}) {
            for (int n : {1, 2, 7, 63, 65, 127, 1001, 4097}) {
                for (int grain : {0, 1, 3, 16}) {
                    std::vector<std::atomic<int>> hits(size_t(begin + n));
                    std::atomic<int> badChunks{0};
                    par.forRange(
                        begin, begin + n,
                        [&](int b, int e) {
                            if (b < begin || e > begin + n || b >= e) ++badChunks;
                            for (int i = b; i < e; ++i) ++hits[size_t(i)];
                        },
                        grain);
                    EXPECT_EQ(badChunks.load(), 0);
                    int wrong = 0;
                    for (int i = 0; i < begin + n; ++i)
                        wrong += hits[size_t(i)].load() != (i >= begin ? 1 : 0);
                    ASSERT_EQ(wrong, 0) << "threads " << threads << " range [" << begin << ", "
                                        << begin + n << ") grain " << grain;
                }
            }
        }
        // Empty and reversed ranges call nothing.
        int calls = 0;
        par.forRange(3, 3, [&](int, int) { ++calls; });
        par.forRange(4, 2, [&](int, int) { ++calls; });
        EXPECT_EQ(calls, 0);
    }
}

TEST(Parallel, ChunkBoundariesDoNotDependOnThreadCount) {
    auto chunks = [](int threads) {
        Parallel par(threads);
        std::vector<std::atomic<int>> startsAt(1001);
        par.forRange(0, 1001, [&](int b, int) { ++startsAt[size_t(b)]; });
        std::vector<int> r;
        for (auto& s : startsAt) r.push_back(s.load());
        return r;
    };
    EXPECT_EQ(chunks(1), chunks(2));
    EXPECT_EQ(chunks(1), chunks(4));
}

TEST(Parallel, ExceptionInAChunkReachesTheCallerAndThePoolSurvives) {
    Parallel par(2);
    // Several chunks throw, on whichever threads run them; one exception reaches the caller
    // (an exception escaping a worker thread would terminate the process instead).
    EXPECT_THROW(par.forRange(
                     0, 1000,
                     [](int b, int) {
                         if (b % 100 == 0) throw Error("chunk failed");
                     },
                     10),
                 Error);
    std::atomic<int> sum{0};
    par.forRange(
        0, 100, [&](int b, int e) { sum += e - b; }, 1);
    EXPECT_EQ(sum.load(), 100);
}

std::vector<float> runRowWork(int threads) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "work", "type": "RowWork"}], "edges": [{"from": "ramp.out", "to": "work.in"}],
        "outputs": ["work.out"]})",
                         r);
    Parallel par(threads);
    Executor ex(*g, par, {}, Extent{61, 97});
    ex.runFrame(1);
    ImageView v = ex.output("work.out");
    return std::vector<float>(v.channel(0), v.channel(0) + v.pixels());
}

TEST(Parallel, GraphOutputIsIdenticalForOneAndTwoThreads) {
    std::vector<float> one = runRowWork(1), two = runRowWork(2);
    ASSERT_EQ(one.size(), two.size());
    // Bitwise, not approximately: every row is computed by the same code in the same order.
    EXPECT_EQ(std::memcmp(one.data(), two.data(), one.size() * sizeof(float)), 0);
    // And the output is not trivially constant (the comparison means something).
    EXPECT_NE(one.front(), one.back());
}

}  // namespace
}  // namespace kestrel::enginetest
