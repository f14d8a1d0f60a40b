#pragma once
// ExrWriter: the sink pass. Writes whatever image arrives at `color` to one EXR per frame
// (half or float), atomically (temporary file in the same folder, then rename), with the graph's
// provenance in the header, and optionally a tone-mapped sRGB PNG preview.
#include <Imath/half.h>

#include <memory>
#include <string>
#include <vector>

#include "KeepPasses.h"
#include "PngPreview.h"
#include "Workspace.h"
#include "kestrel/Declare.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Kestrel.h"

namespace kestrel::exr {

class ExrWriter : public Pass {
public:
    enum class PixelType { Auto, Half, Float };
    struct Params {
        std::string path = "out/frame.####.exr";
        PixelType pixelType = PixelType::Auto;  // auto: the source's (resolved at compile time)
        std::string compression = "zip";        // the name OpenEXR's compression is chosen by
        int zipLevel = 4;
        std::string preview;
        float exposure = 0.f;
        display::ToneCurve tonemap = display::ToneCurve::Aces;
        bool keepPasses = false;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h).
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        InputPort color, alpha;
    };
    static const Declaration& declaration();

    static PassDesc describe() { return declaration().desc(); }
    explicit ExrWriter(const ParamValues& params);

    void resolve(ResolveContext& rc) override;
    void beginRun(const RunContext& rc) override;
    void execute(FrameContext& ctx, PassIO& io) override;
    bool frameWritten(int64_t frame, const std::string& provenance) const override;
    std::string recordedProvenance(int64_t frame) const override;

private:
    /// `lent`: the writer's idle planes (PassIO::idlePlanes), for the ZIP encoder's chunk buffers.
    void writeExr(const ImageView& img, const std::string& path, const FrameContext& ctx,
                  const Workspace& lent);
    struct Converter;  // the frame's values as written (sanitised), ExrWriter.cpp
    /// Other compressions than ZIP: the frame converted whole, written by OpenEXR.
    void writeThroughOpenExr(const Imf::Header& header, const std::string& tmp, Converter& convert,
                             const FrameContext& ctx);
    /// keepPasses: the output's own channels and the input frame's others, through OpenEXR.
    void writeKeeping(const Imf::Header& header, const std::string& tmp, int64_t frame,
                      const OwnRow& own, int threads) const;
    /// Warns (once per run each) of the values written as 0 (NaN) or clamped to the range.
    void warnSanitised(int64_t frameNumber, size_t nans, size_t clamped, bool asHalf, float limit);
    /// Throws when KESTREL_TEST_WRITE_FAULT names this step and frame (tests only).
    void injectFault(const char* step, int64_t frame) const;

    Params p_;
    FramePattern path_;
    std::unique_ptr<FramePattern> preview_;
    std::unique_ptr<OcioView> view_;    ///< previews through $OCIO's default view, if set
    bool half_ = false;                 // pixelType half, or auto where the source's colour is half
    std::unique_ptr<KeptSource> kept_;  ///< keepPasses: the loader's file per frame (resolve)
    std::string faultStep_;             // empty unless a test injects a write fault
    int64_t faultFrame_ = 0;

    // Per-run warning flags (logging only, not image state) and conversion scratch.
    bool warnedRange_ = false, warnedNaN_ = false;
    std::vector<half> halfScratch_;  ///< the frame converted, for compressions other than ZIP
    std::vector<float> floatScratch_;
};

}  // namespace kestrel::exr
