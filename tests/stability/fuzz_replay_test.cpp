// Replays every file of the fuzz corpora (fuzz/corpus/<target>/: seeds and inputs that once
// crashed a fuzzer) through the fuzz targets' logic, so fixed fuzz findings stay fixed in the
// ordinary (and the sanitizer) test run. Each input must be read or rejected with a
// kestrel::Error; a crash or another exception fails the test.
#include <gtest/gtest.h>
#include <kestrel/Graph.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "FuzzTargets.h"
#include "StabilityRig.h"

namespace stability {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> corpus(const std::string& target) {
    std::vector<fs::path> files;
    const fs::path dir = fs::path(KESTREL_SOURCE_DIR) / "fuzz" / "corpus" / target;
    if (fs::is_directory(dir))
        for (const auto& e : fs::directory_iterator(dir))
            if (e.is_regular_file()) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    return files;
}

std::vector<uint8_t> bytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(FuzzReplay, GraphCorpus) {
    const auto files = corpus("graph_fuzzer");
    ASSERT_FALSE(files.empty());
    int compiled = 0;
    for (const auto& f : files) {
        SCOPED_TRACE(f.filename().string());
        const auto b = bytes(f);
        compiled += kestrel::fuzz::graphTarget(b.data(), b.size(), registry()) ? 1 : 0;
    }
    // The shipped graphs are seeds: they must compile (validateOnly).
    EXPECT_GE(compiled, 3);
}

TEST(FuzzReplay, ExrCorpus) {
    const auto files = corpus("exr_fuzzer");
    ASSERT_FALSE(files.empty());
    const fs::path scratch =
        fs::temp_directory_path() / ("kestrel-exr-replay-" + std::to_string(::getpid()));
    fs::create_directories(scratch);
    int read = 0;
    for (const auto& f : files) {
        SCOPED_TRACE(f.filename().string());
        const auto b = bytes(f);
        read += kestrel::fuzz::exrTarget(b.data(), b.size(), scratch) ? 1 : 0;
    }
    fs::remove_all(scratch);
    // The generated seeds are valid files: most are read (measured: see the count below).
    std::printf("%d of %zu EXR corpus files read\n", read, files.size());
    EXPECT_GE(read, 10);
}

TEST(FuzzReplay, NumberOverflowInGraphJsonIsAGraphError) {
    // Regression (graph_fuzzer seed errors.json): nlohmann's out_of_range.406 escaped parseGraph.
    EXPECT_THROW(kestrel::parseGraph(R"({"kestrel": 1e400})"), kestrel::GraphError);
}

}  // namespace
}  // namespace stability
