// The loader's declaration: its outputs (loaderOutputs(), the data the plans build their recipes
// from) and parameters, each default written once, in ExrLoader::Params.
#include <cassert>

#include "ExrLoader.h"

namespace kestrel::exr {

ExrLoader::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "ExrLoader",
          "Reads AOV frames from EXR files (canonical, Blender multilayer or GAMES202 layout); "
          "only channels a consumer needs are decoded") {
    for (const auto& o : loaderOutputs()) {
        outputs.push_back(output(o.name, o.format, o.description));
        const std::string_view name = o.name;
        if (name == "color") color = outputs.back();
        if (name == "diffuse") diffuse = outputs.back();
        if (name == "emission") emission = outputs.back();
    }
    param("path", &Params::path,
          "frame pattern (frame_####.exr, %04d, beauty_%d.exr) or a GAMES202 folder");
    param("layout", &Params::layout, {"auto", "canonical", "blender", "games202"},
          "file layout; auto: kestrel.layout attribute, Blender channels, beauty_*.exr");
    param("layer", &Params::layer,
          "Blender view layer to read; empty: the only one (a file with several is refused, "
          "naming them)");
    param("camera", &Params::camera,
          "Blender camera.json; empty: look beside the frames, then one folder up");
    param("channels", &Params::channels,
          "override output channels: out=Layer[*Layer][+...],... e.g. albedo=ViewLayer.DiffCol "
          "(empty expression: leave the output out)");
    param("antiAliased", &Params::antiAliased, {"auto", "true", "false"},
          "whether the render is anti-aliased (the jittered* albedos present); auto: the pixel "
          "filter camera.json or kestrel.pixelFilterWidth states, else the first frame's depth "
          "jitter");
    param("maxPixels", &Params::maxPixels, 1, int64_t(1) << 40,
          "largest data or display window accepted (pixels), checked before allocating; "
          "OpenEXR's per-chunk buffers are held to 16 bytes per maxPixels pixel");
    param("prefetch", &Params::prefetch,
          "decode the next frame on a background thread while the graph computes this one; "
          "costs a second set of the channels read (4 bytes per channel per pixel: about 160 MB, "
          "76 B/px, for 19 channels at 1920x1080), so it is off by default (svgf.json's whole "
          "run stays under 256 B/px); pays off with a spare core");
}

const ExrLoader::Declaration& ExrLoader::declaration() {
    static const Declaration d;
    return d;
}

ExrLoader::ExrLoader(const ParamValues& p) : p_(declaration().read(p)) {}

ExrLoader::~ExrLoader() {
    cancel_ = true;
    joinPrefetch();
}

const OutputPort& ExrLoader::port(const Recipe* r) const {
    // Plans build one recipe per loader output, in declaration order (ChannelPlan.cpp).
    assert(plan_.recipes.size() == declaration().outputs.size());
    return declaration().outputs[size_t(r - plan_.recipes.data())];
}

}  // namespace kestrel::exr
