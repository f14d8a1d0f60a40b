#pragma once
// VirtualMotion: the motion of what a mirror shows, not of the mirror (NRD ReBLUR's "virtual
// motion"; ../shared/seeds/002_*.txt). A specular chain reprojected with the surface's own
// motion (Blender's Vector pass) takes last frame's reflection from where the floor was, not
// from where the reflected point was seen, and the reflection smears in time. For a planar
// mirror the reflected point's virtual image lies on the camera ray at the ray's path length
// through the bounce (Cycles' Denoising Depth: the loader's pathLength); projecting that point
// with last frame's camera gives where the reflection was. Elsewhere, and where the virtual
// image is not consistent with last frame's path length (a curved mirror, a moving reflected
// object), the surface motion is kept.
#include <kestrel/Kestrel.h>

class VirtualMotionPass final : public kestrel::Pass {
public:
    struct Params {
        /// Largest relative difference between the virtual point's distance from last frame's
        /// camera and last frame's path length at the pixel it projects to.
        float tolerance = 0.02f;
    };
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort motion, reflection, pathLength, prevPathLength, taps;
        kestrel::OutputPort motionOut;  ///< the port `motion`
        kestrel::OutputPort tapsOut;    ///< the port `taps`
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit VirtualMotionPass(const kestrel::ParamValues& p) : p_(declaration().read(p)) {}
    void resolve(kestrel::ResolveContext& rc) override;
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

private:
    Params p_;
};
