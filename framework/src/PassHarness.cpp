#include "kestrel/testing/PassHarness.h"

#include <algorithm>

#include "ParamCheck.h"

namespace kestrel::testing {

namespace {
// Ports are looked up by name AND kind: a pass may have an input and an output of the same name
// (ATrous: color -> color).
const PortDesc* findPortOfKind(const PassDesc& d, std::string_view name, PortKind kind) {
    for (const auto& p : d.ports)
        if (p.name == name && p.kind == kind) return &p;
    return nullptr;
}
}  // namespace

ParamValues makeParams(const PassDesc& desc, const std::map<std::string, ParamValue>& overrides) {
    nlohmann::json obj = nlohmann::json::object();
    for (const auto& [k, v] : overrides) obj[k] = detail::paramValueToJson(v);
    std::vector<Diagnostic> diags;
    ParamValues values = detail::checkParams(desc, obj, desc.type, diags);
    if (!diags.empty()) throw GraphError(std::move(diags));
    return values;
}

PassHarness::PassHarness(PassDesc desc, std::unique_ptr<Pass> pass, Extent extent, int threads)
    : desc_(std::move(desc)),
      pass_(std::move(pass)),
      extent_(extent),
      parallel_(std::make_unique<Parallel>(threads)) {
    for (const auto& p : desc_.ports)
        if (p.kind == PortKind::Output) used_.push_back(p.name);
    run_.graphName = "test";
}

PassHarness::PassHarness(PassHarness&&) noexcept = default;
PassHarness::~PassHarness() = default;

void PassHarness::lendIdlePlanes(int count, float fill) {
    idleStorage_.clear();
    idle_.clear();
    for (int i = 0; i < count; ++i) {
        idleStorage_.push_back(allocatePlane(extent_.pixels()));
        std::fill_n(idleStorage_.back().get(), extent_.pixels(), fill);
        idle_.push_back(idleStorage_.back().get());
    }
}

void PassHarness::bind(std::string_view input, const ImageView& image, bool valid) {
    const PortDesc* p = findPortOfKind(desc_, input, PortKind::Input);
    if (!p) throw Error(desc_.type + " has no input '" + std::string(input) + "'");
    inputs_[std::string(input)] = Bound{image, valid};
}

void PassHarness::unbind(std::string_view input) {
    auto it = inputs_.find(input);
    if (it != inputs_.end()) inputs_.erase(it);
}

void PassHarness::useOutputs(const std::vector<std::string>& outputs) {
    used_ = outputs;
}

void PassHarness::run() {
    ctx.extent = extent_;
    ctx.scene = &scene;
    ctx.previousScene = &previousScene;
    ctx.parallel = parallel_.get();
    ctx.run = &run_;
    if (auto e = pass_->beginFrame(ctx)) {
        extent_ = *e;
        ctx.extent = *e;
    }
    for (const auto& name : used_) {
        const PortDesc* p = findPortOfKind(desc_, name, PortKind::Output);
        if (!p) throw Error(desc_.type + " has no output '" + name + "'");
        auto it = outputs_.find(name);
        Format f = p->format == Format::Any ? Format::Float3 : p->format;
        if (it == outputs_.end() || it->second.extent() != extent_)
            outputs_[name] = Image(extent_, f);
    }
    pass_->execute(ctx, *this);
    ++ctx.frameIndex;
    ++ctx.frameNumber;
}

const Image& PassHarness::out(std::string_view output) const {
    auto it = outputs_.find(output);
    if (it == outputs_.end()) throw Error("output '" + std::string(output) + "' was not produced");
    return it->second;
}

bool PassHarness::hasInput(std::string_view name) const {
    auto it = inputs_.find(name);
    return it != inputs_.end() && it->second.valid;
}

const ImageView& PassHarness::input(std::string_view name) const {
    auto it = inputs_.find(name);
    if (it == inputs_.end() || !it->second.valid)
        throw Error(desc_.type + ": input '" + std::string(name) + "' is not bound");
    return it->second.view;
}

bool PassHarness::historyValid(std::string_view name) const {
    return hasInput(name);
}

bool PassHarness::hasOutput(std::string_view name) const {
    for (const auto& u : used_)
        if (u == name) return true;
    return false;
}

const ImageView& PassHarness::output(std::string_view name) {
    auto it = outputs_.find(name);
    if (it == outputs_.end())
        throw Error(desc_.type + ": output '" + std::string(name) + "' is not consumed");
    return it->second.view();
}

}  // namespace kestrel::testing
