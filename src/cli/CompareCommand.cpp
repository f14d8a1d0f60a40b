// `kestrel compare OUT REF`: error metrics of an output sequence against a reference. The work is
// in kestrel_eval (eval/Compare.h); this file only maps options and exit codes.
#include <eval/Compare.h>
#include <eval/Regions.h>
#include <kestrel/Error.h>
#include <kestrel/FramePattern.h>

#include <iostream>
#include <memory>

#include "Commands.h"
#include "Common.h"

namespace kestrel::cli {
namespace {

struct CompareArgs {
    std::string out, ref, frames, toneMap = "reinhard", layer, refLayer, regions;
    bool json = false;
};

int runCompare(const CompareArgs& a) {
    eval::CompareOptions o;
    o.outPattern = a.out;
    o.refPattern = a.ref;
    o.outLayer = a.layer;
    o.refLayer = a.refLayer;
    o.toneMap = eval::parseToneMap(a.toneMap).value_or(eval::ToneMap::Reinhard);
    try {  // bad --frames text or pattern syntax: usage errors
        if (!a.frames.empty()) o.frames = parseFrameRange(a.frames);
        FramePattern{a.out}, FramePattern{a.ref};
    } catch (const Error& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    }
    const eval::CompareResult r = eval::compareSequences(o);  // Error -> exit 1 in main
    for (const auto& f : r.frames) {
        const auto& m = f.metrics;
        if (m.nonFiniteOutput || m.nonFiniteReference)
            std::cerr << "warning: " << (f.frame ? "frame " + std::to_string(*f.frame) + ": " : "")
                      << m.nonFiniteOutput << " output and " << m.nonFiniteReference
                      << " reference pixels hold NaN/Inf (counted; NaN -> 0, Inf -> +-FLT_MAX)\n";
    }
    std::optional<eval::RegionStats> regions;
    if (!a.regions.empty()) {
        std::vector<int64_t> frames;
        for (const auto& f : r.frames)
            if (f.frame) frames.push_back(*f.frame);
        if (frames.empty()) {
            std::cerr << "error: --regions needs frame patterns (OUTPUT and REFERENCE with #)\n";
            return 2;
        }
        auto plugins = loadPlugins();
        regions =
            eval::compareRegions(plugins->registry, a.out, a.ref, a.regions, frames, o.toneMap);
    }
    if (a.json) {
        nlohmann::json j = eval::toJson(r);
        if (regions) j["regions"] = eval::regionsToJson(*regions);
        std::cout << j.dump(2) << "\n";
    } else {
        std::cout << eval::formatTable(r);
        if (regions)
            std::cout << "\nper region (PSNR over the frames; regions from " << a.regions << "):\n"
                      << eval::formatRegionTable(*regions);
    }
    return 0;
}

}  // namespace

void addCompareCommand(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand(
        "compare",
        "Error of an output sequence against a reference: relMSE, PSNR, SSIM and temporal "
        "instability per frame and their mean");
    auto args = std::make_shared<CompareArgs>();
    cmd->add_option("OUTPUT", args->out,
                    "Output frames: frame_####.exr, frame_%04d.exr or one file")
        ->required();
    cmd->add_option("REFERENCE", args->ref, "Reference frames, same syntax")->required();
    cmd->add_option("--frames", args->frames,
                    "Frames to compare: 7, 1-100, 1-100x2, 3,4,10-20x2 (default: every output "
                    "frame found on disk)");
    cmd->add_flag("--json", args->json, "Print JSON on stdout instead of a table");
    cmd->add_option("--tonemap", args->toneMap,
                    "Tone map before PSNR, SSIM and temporal: reinhard = (x/(1+x))^(1/2.2), "
                    "clamp = clamp(x,0,1), srgb = sRGB of clamp(x,0,1)")
        ->check(CLI::IsMember({"reinhard", "clamp", "srgb"}))
        ->capture_default_str();
    cmd->add_option("--layer", args->layer,
                    "RGB layer of the output files (default: plain R,G,B, else *.Combined, else "
                    "the only RGB layer)");
    cmd->add_option("--ref-layer", args->refLayer, "RGB layer of the reference files");
    cmd->add_option("--regions", args->regions,
                    "The run's input frames (as run --input): also report the error per region "
                    "(background, emissive, glossy, textured, disoccluded, flat; from its "
                    "G-buffer) for the output and for the 1-spp input, and the reference's own "
                    "flicker on flat surfaces of point-sampled renders");
    cmd->callback([&action, args] { action = [args] { return runCompare(*args); }; });
}

}  // namespace kestrel::cli
