#pragma once
// Vignette: darkens colour towards the image corners, the way a real lens does. A minimal,
// complete example of an out-of-tree Kestrel pass: ports and ranged parameters declared once
// (kestrel/Declare.h) and read through what the declaration returns, a threaded row loop,
// NaN/Inf-safe output.
#include <kestrel/Kestrel.h>

namespace vignette {

/// Gain at normalised radius r (0 at the centre, 1 in the corners): 1 inside `radius`, then a
/// smoothstep falloff reaching 1 - strength in the corners. Always in [1 - strength, 1].
float vignetteGain(float r, float radius, float strength);

class VignettePass final : public kestrel::Pass {
public:
    struct Params {
        float strength = 0.5f;  ///< the default, written once
        float radius = 0.5f;
    };
    /// Ports and parameters: the PassDesc `kestrel passes` shows is derived from them, and the
    /// pass reaches its ports through these handles (a misspelt port does not compile).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color;
        kestrel::OutputPort colorOut;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit VignettePass(const kestrel::ParamValues& params) : p_(declaration().read(params)) {}
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
};

}  // namespace vignette
