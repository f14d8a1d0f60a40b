#pragma once
// Select: forwards `preferred` when the scene can produce it, else `fallback`. Decided at compile
// time (never executes): lets one graph use the best variant the scene supports, e.g. the
// diffuse/specular split when the loader has it and a single albedo otherwise.
#include <kestrel/Kestrel.h>

class SelectPass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit SelectPass(const kestrel::ParamValues&) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;
};
