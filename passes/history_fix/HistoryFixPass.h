#pragma once
// HistoryFix: fills the colour of pixels with a short history (a disocclusion, a camera cut, the
// first frame, a history anti-lag shortened) from their neighbours on the same surface, before
// the variance estimate and the spatial filters see it. After NRD ReBLUR's history fix: the
// blur's stride and its share of the result shrink as the history grows, its weights are
// geometry and each neighbour's own history length, never luminance.
//
// Why: with one or two samples a pixel's colour is often 0 (most 1-spp paths of dim indirect
// light carry nothing), and the filters downstream stop at geometry (normals at sigmaN 128 on a
// curved surface) and at luminance differences scaled by a variance estimated from those same few
// samples, often 0: such a pixel kept its 1-spp black among filled neighbours (a speckle). The
// normals themselves can isolate a pixel (Cycles' Denoising Normal follows each sample through
// glass and mirrors): where its neighbours hold under a quarter of the weight, the fill is redone
// on depth and object id alone, skipping only taps that face away.
#include <kestrel/Kestrel.h>

class HistoryFixPass final : public kestrel::Pass {
public:
    struct Params {
        float frames = 4.f;
        int stride = 1;
        float normalPower = 8.f;
        float depthSlack = 0.01f;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        kestrel::InputPort color, historyLength, depth, normal, objectId;
        kestrel::OutputPort colorOut;
    };
    static const Declaration& declaration();

    static kestrel::PassDesc describe() { return declaration().desc(); }
    explicit HistoryFixPass(const kestrel::ParamValues& p);
    void execute(kestrel::FrameContext& ctx, kestrel::PassIO& io) override;

    /// The parameters as the kernel uses them.
    struct Settings {
        float frames;       ///< pixels with historyLength below this are filled
        int stride;         ///< tap spacing (pixels) at historyLength 1
        float normalPower;  ///< weight max(0, n_p . n_q)^normalPower
        float depthSlack;   ///< relative depth tolerance beyond the depth slope
    };

private:
    Settings s_;
};
