// Per-frame engine overhead: a graph of 10 trivial passes on a 1x1 image, so the time per
// iteration is the executor's own bookkeeping (beginFrame calls, binding, timing, swap).
// Built as `engine_overhead_bench`, not registered with ctest: run it by hand.
// Measured (Release, -march=native, 2 shared cores at load average ~14): 1.4 us CPU per frame
// (0.14 us per pass), 4.9 us wall, for 1 and 2 threads alike (1x1 never reaches the pool).
#include <benchmark/benchmark.h>

#include <string>

#include "TestPasses.h"

namespace {

using namespace kestrel;

std::string tenPassGraph() {
    std::string passes = R"({"name": "p0", "type": "Const"})", edges;
    for (int i = 1; i < 10; ++i) {
        std::string n = "p" + std::to_string(i), prev = "p" + std::to_string(i - 1);
        passes += R"(, {"name": ")" + n + R"(", "type": "AddOne"})";
        edges += std::string(i > 1 ? ", " : "") + R"({"from": ")" + prev + R"(.out", "to": ")" + n +
                 R"(.in"})";
    }
    return R"({"kestrel": 1, "passes": [)" + passes + R"(], "edges": [)" + edges +
           R"(], "outputs": ["p9.out"]})";
}

void BM_TenTrivialPassesOneByOne(benchmark::State& state) {
    Registry registry = enginetest::testRegistry();
    auto graph = enginetest::compileText(tenPassGraph(), registry);
    Parallel parallel(int(state.range(0)));
    Executor executor(*graph, parallel, {}, Extent{1, 1});
    int64_t frame = 0;
    for (auto _ : state) {
        executor.runFrame(frame++);
        benchmark::DoNotOptimize(executor.output("p9.out").planes[0][0]);
    }
    state.SetLabel("10 passes, 1x1");
}
BENCHMARK(BM_TenTrivialPassesOneByOne)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
