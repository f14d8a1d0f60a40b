#include <kestrel/testing/PassHarness.h>

#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "ExrLoader.h"
#include "FuzzTargets.h"

namespace kestrel::fuzz {

namespace {

/// Records which outputs the loader marks absent (the rest are consumed).
class Resolve final : public ResolveContext {
public:
    bool isBound(std::string_view) const override { return false; }
    void forward(std::string_view, std::string_view) override {}
    void setAbsent(std::string_view output, std::string) override { absent.emplace(output); }
    void note(std::string) override {}
    int64_t firstFrame() const override { return 1; }
    std::string_view passName() const override { return "input"; }
    std::set<std::string, std::less<>> absent;
};

}  // namespace

bool exrTarget(const uint8_t* data, size_t size, const std::filesystem::path& scratchDir) {
    const std::filesystem::path file = scratchDir / "fuzz.0001.exr";
    {
        std::ofstream out(file, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    }
    try {
        // A small pixel limit: a header claiming a huge window, or chunks whose buffers exceed
        // 16 bytes x 2^16 = 1 MB, is refused before allocation (and keeps each run fast).
        auto h = testing::PassHarness::make<exr::ExrLoader>(
            {1, 1},
            {{"path", (scratchDir / "fuzz.####.exr").string()}, {"maxPixels", int64_t(1) << 16}});
        Resolve rc;
        h.pass().resolve(rc);
        std::vector<std::string> outputs;
        for (const auto& p : exr::ExrLoader::describe().ports)
            if (p.kind == PortKind::Output && !rc.absent.count(p.name)) outputs.push_back(p.name);
        if (outputs.empty()) return false;
        h.useOutputs(outputs);
        h.ctx.frameNumber = 1;
        h.run();
        return true;
    } catch (const Error&) {
        return false;  // a FrameError or Error naming the problem: the expected outcome
    }
}

}  // namespace kestrel::fuzz
