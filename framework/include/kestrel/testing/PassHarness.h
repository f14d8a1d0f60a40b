#pragma once
// Runs one pass outside a graph, for unit tests of passes (the project's and plugin authors').
//
//   auto h = kestrel::testing::PassHarness::make<DemodulatePass>({4, 4}, {{"albedoFloor", 0.01}});
//   h.bind("color", colorImage);
//   h.run();
//   const kestrel::Image& out = h.out("illumination");
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "kestrel/Image.h"
#include "kestrel/Pass.h"

namespace kestrel::testing {

/// Declared defaults with `overrides` applied and validated (throws Error naming a bad one).
ParamValues makeParams(const PassDesc& desc, const std::map<std::string, ParamValue>& overrides);

class PassHarness : public PassIO {
public:
    PassHarness(PassDesc desc, std::unique_ptr<Pass> pass, Extent extent, int threads = 1);
    ~PassHarness() override;

    template <class T>
    static PassHarness make(Extent extent, const std::map<std::string, ParamValue>& params = {},
                            int threads = 1) {
        PassDesc d = T::describe();
        auto pass = std::make_unique<T>(makeParams(d, params));
        return PassHarness(std::move(d), std::move(pass), extent, threads);
    }
    PassHarness(PassHarness&&) noexcept;

    /// Binds an input (for history inputs, `valid` says whether the history is valid).
    void bind(std::string_view input, const ImageView& image, bool valid = true);
    void unbind(std::string_view input);
    /// Restrict which outputs are consumed (default: all declared outputs).
    void useOutputs(const std::vector<std::string>& outputs);
    /// Calls beginFrame (sources) and execute once.
    void run();
    const Image& out(std::string_view output) const;
    Pass& pass() { return *pass_; }
    /// Gives the pass `count` idle planes (PassIO::idlePlanes) of the frame's size, each filled
    /// with `fill` (NaN shows a pass reading what it did not write), as a graph's plan would.
    void lendIdlePlanes(int count, float fill);
    std::span<float* const> idlePlanes() const override { return idle_; }

    SceneData scene, previousScene;
    FrameContext ctx;

    // PassIO
    bool hasInput(std::string_view name) const override;
    const ImageView& input(std::string_view name) const override;
    bool historyValid(std::string_view name) const override;
    bool hasOutput(std::string_view name) const override;
    const ImageView& output(std::string_view name) override;

private:
    struct Bound {
        ImageView view;
        bool valid = true;
    };
    PassDesc desc_;
    std::unique_ptr<Pass> pass_;
    Extent extent_;
    std::unique_ptr<Parallel> parallel_;
    std::map<std::string, Bound, std::less<>> inputs_;
    std::map<std::string, Image, std::less<>> outputs_;
    std::vector<std::string> used_;
    RunInfo run_;
    std::vector<PlaneStorage> idleStorage_;
    std::vector<float*> idle_;
};

}  // namespace kestrel::testing
