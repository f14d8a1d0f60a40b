#pragma once
// Select: forwards `preferred` when the scene can produce it, else `fallback`. Decided at compile
// time (never executes): lets one graph use the best variant the scene supports, e.g. the
// diffuse/specular split when the loader has it and a single albedo otherwise.
#include <kestrel/Kestrel.h>

class SelectPass final : public kestrel::Pass {
public:
    struct Params {};
    /// Ports, declared once (kestrel/Declare.h); Select has no parameters.
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort preferred, fallback;
        kestrel::OutputPort out;  ///< the port `output`
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit SelectPass(const kestrel::ParamValues&) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;
};
