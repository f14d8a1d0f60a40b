// Replays every file of the fuzz corpora (fuzz/corpus/<target>/: seeds and inputs that once
// crashed a fuzzer) through the fuzz targets' logic, so fixed fuzz findings stay fixed in the
// ordinary (and the sanitizer) test run. Each input must be read or rejected with a
// kestrel::Error; a crash or another exception fails the test.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <kestrel/Graph.h>
#include <kestrel/testing/PassHarness.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <iterator>

#include "ExrLoader.h"
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

/// A scratch folder of its own, removed at the end.
struct Scratch {
    fs::path dir = fs::temp_directory_path() / ("kestrel-replay-" + std::to_string(::getpid()));
    Scratch() { fs::create_directories(dir); }
    ~Scratch() { fs::remove_all(dir); }
};

/// A resolve context that binds nothing and records nothing: the loader's own checks only.
class QuietResolve final : public kestrel::ResolveContext {
public:
    bool isBound(std::string_view) const override { return false; }
    void forward(std::string_view, std::string_view) override {}
    void setAbsent(std::string_view, std::string) override {}
    void note(std::string) override {}
    int64_t firstFrame() const override { return 1; }
    std::string_view passName() const override { return "input"; }
};

/// Frame 1 of `pattern` read by the ExrLoader with its default limits: the error it gives
/// (a kestrel::Error), or "" when the frame was read.
std::string loaderError(const std::string& pattern) {
    try {
        auto h = kestrel::testing::PassHarness::make<kestrel::exr::ExrLoader>({1, 1},
                                                                              {{"path", pattern}});
        QuietResolve rc;
        h.pass().resolve(rc);
        h.useOutputs({"color"});
        h.ctx.frameNumber = 1;
        h.run();
        return "";
    } catch (const kestrel::Error& e) {
        return e.what();
    }
}

TEST(FuzzReplay, OversizedHeadersAreRefusedBeforeAllocatingAtTheDefaultLimits) {
    // The corpus replay runs under a 2^16-pixel limit, which refuses them first; under the
    // default limit the header's own claims against the file's size (its offset table, its
    // pixels) must refuse them, before any allocation of that size.
    const auto files = corpus("exr_fuzzer");
    int oversized = 0;
    Scratch s;
    for (const auto& f : files) {
        if (f.filename().string().rfind("oversized-", 0) != 0) continue;
        SCOPED_TRACE(f.filename().string());
        ++oversized;
        fs::copy_file(f, s.dir / "o.0001.exr", fs::copy_options::overwrite_existing);
        const std::string error = loaderError((s.dir / "o.####.exr").string());
        EXPECT_NE(error.find("o.0001.exr"), std::string::npos) << error;
        EXPECT_NE(error.find("refused before allocating"), std::string::npos) << error;
    }
    EXPECT_EQ(oversized, 2) << "fuzz/make_exr_seeds.cpp writes two oversized-window seeds";
}

TEST(FuzzReplay, FifoWhereAFrameIsExpectedIsRefusedWithoutHanging) {
    // A FIFO cannot be a corpus file (git stores no FIFOs): made here. Opened for reading it
    // would block until a writer comes, so the read runs apart and is released if it hangs.
    Scratch s;
    const fs::path fifo = s.dir / "p.0001.exr";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    auto read = std::async(std::launch::async,
                           [&] { return loaderError((s.dir / "p.####.exr").string()); });
    if (read.wait_for(std::chrono::seconds(20)) != std::future_status::ready) {
        const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);  // lets the reader go
        if (fd >= 0) ::close(fd);
        ADD_FAILURE() << "reading a FIFO hung";
    }
    const std::string error = read.get();
    EXPECT_NE(error.find("p.0001.exr"), std::string::npos) << error;
}

TEST(FuzzReplay, DevicesAndFoldersWhereAFrameIsExpectedAreRefused) {
    // Devices cannot be corpus files either: links to them, and a folder named like a frame.
    Scratch s;
    for (const char* device : {"/dev/zero", "/dev/null", "/dev/urandom"}) {
        SCOPED_TRACE(device);
        fs::remove(s.dir / "d.0001.exr");
        fs::create_symlink(device, s.dir / "d.0001.exr");
        const std::string error = loaderError((s.dir / "d.####.exr").string());
        EXPECT_NE(error.find("d.0001.exr"), std::string::npos) << error;
    }
    fs::create_directory(s.dir / "f.0001.exr");
    const std::string error = loaderError((s.dir / "f.####.exr").string());
    EXPECT_NE(error.find("f.0001.exr"), std::string::npos) << error;
}

TEST(FuzzReplay, NumberOverflowInGraphJsonIsAGraphError) {
    // Regression (graph_fuzzer seed errors.json): nlohmann's out_of_range.406 escaped parseGraph.
    EXPECT_THROW(kestrel::parseGraph(R"({"kestrel": 1e400})"), kestrel::GraphError);
}

}  // namespace
}  // namespace stability
