#pragma once
// AntiLag: shortens the reprojected history where the lighting changed, so a light switched off,
// a moving shadow or a dimming sky does not linger for the frames the temporal filter needs to
// forget it (SVGF's "lagging shadows"). After A-SVGF (Schied et al., HPG 2018: a temporal
// gradient lambda raises the current frame's blend weight a to (1 - lambda) a + lambda), with
// the gradient estimated from the frames SVGF has, not from re-shaded samples: the difference of
// the current frame's and the history's mean luminance over a window, less what the current
// frame's noise explains, relative to the smaller of the two. The weight it raises is the history
// length's, 1 / (hl + 1); TemporalAccumulation's alpha floor applies after, so a small lambda on
// a long history changes nothing.
#include <kestrel/Kestrel.h>

class AntiLagPass final : public kestrel::Pass {
public:
    static constexpr int kMaxRadius = 16;  ///< the radius parameter's bound

    struct Params {
        int radius = 4;     ///< window half-width in pixels
        float sigma = 4.f;  ///< standard errors of the current window mean a difference must exceed
        bool enabled = true;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, history, historyLength;
        kestrel::OutputPort historyLengthOut;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit AntiLagPass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
};
