#pragma once
// JointBilateral (GAMES202 homework 5, section 2.1): single-frame joint bilateral filter guided
// by the noise-free G-buffer,
//   J(i,j) = exp(-|i-j|^2 / (2 sp^2) - |C_i-C_j|^2 / (2 sc^2) - D_normal^2 / (2 sn^2)
//                - D_plane^2 / (2 sd^2)),
//   D_normal = acos(n_i . n_j),  D_plane = n_i . (P_j - P_i) / |P_j - P_i| (0 when P_j = P_i),
// over a (2 radius + 1)^2 window; output = sum_j J C_j / sum_j J.
// Background pixels (objectId -1, zero normal, background depth, non-finite position) are
// passed through and never contribute; with objectId bound, pixels of other objects do not
// contribute either.
#include <kestrel/Kestrel.h>

namespace kestrel::passes {

class JointBilateralPass final : public Pass {
public:
    struct Params {
        // doubles: the kernel constants below are computed from them in double
        double sigmaCoord = 32.0, sigmaColor = 0.6, sigmaNormal = 0.1, sigmaPlane = 0.1;
        int radius = 16;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        InputPort color, normal, position, depth, objectId;
        OutputPort colorOut;
    };
    static const Declaration& declaration();

    static PassDesc describe() { return declaration().desc(); }
    explicit JointBilateralPass(const ParamValues& params);
    void execute(FrameContext& ctx, PassIO& io) override;

    /// Kernel constants: each inverse is 1 / (2 sigma^2) times log2(e) (base-2 exponent).
    struct Settings {
        int radius = 16;
        float invTwoSigmaCoord2 = 0, invTwoSigmaColor2 = 0, invTwoSigmaNormal2 = 0,
              invTwoSigmaPlane2 = 0;
    };

private:
    Settings s_;
};

}  // namespace kestrel::passes
