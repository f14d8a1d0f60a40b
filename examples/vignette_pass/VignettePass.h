#pragma once
// Vignette: darkens colour towards the image corners, the way a real lens does. A minimal,
// complete example of an out-of-tree Kestrel pass: ports with formats, ranged parameters read
// once in the constructor, a threaded row loop, NaN/Inf-safe output.
#include <kestrel/Kestrel.h>

namespace vignette {

/// Gain at normalised radius r (0 at the centre, 1 in the corners): 1 inside `radius`, then a
/// smoothstep falloff reaching 1 - strength in the corners. Always in [1 - strength, 1].
float vignetteGain(float r, float radius, float strength);

class VignettePass final : public kestrel::Pass {
public:
    static kestrel::PassDesc describe();
    explicit VignettePass(const kestrel::ParamValues& params);
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    float strength_ = 0.5f;
    float radius_ = 0.5f;
};

}  // namespace vignette
