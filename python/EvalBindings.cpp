// The metrics of `kestrel compare` (per frame and per region) as plain records, EXR reading and
// the procedural scene generator (test data without a renderer).
#include <eval/Compare.h>
#include <eval/ExrRgb.h>
#include <eval/Metrics.h>
#include <eval/Regions.h>
#include <kestrel/FramePattern.h>
#include <pybind11/stl.h>
#include <scenegen/SceneGen.h>

#include "Arrays.h"
#include "Bindings.h"

namespace py = pybind11;

namespace kestrel::python {
namespace {

eval::ToneMap toneMapArg(const std::string& name) {
    if (auto t = eval::parseToneMap(name)) return *t;
    throw Error("--tonemap " + name + ": expected reinhard, clamp or srgb");
}

/// compare's JSON ({"frames": [...], "mean": {...}}) as Python objects: the same numbers and
/// names `kestrel compare --json` prints.
py::object compare(const std::string& out, const std::string& ref, const py::object& frames,
                   const std::string& toneMap, const std::string& layer,
                   const std::string& refLayer) {
    eval::CompareOptions o;
    o.outPattern = out;
    o.refPattern = ref;
    o.toneMap = toneMapArg(toneMap);
    o.outLayer = layer;
    o.refLayer = refLayer;
    if (py::isinstance<py::str>(frames))
        o.frames = parseFrameRange(frames.cast<std::string>());
    else if (!frames.is_none())
        o.frames = frames.cast<std::vector<int64_t>>();
    eval::CompareResult r;
    {
        py::gil_scoped_release unlocked;
        r = eval::compareSequences(o);
    }
    return fromJson(eval::toJson(r).dump());
}

/// `kestrel compare --regions`: one record per region ({"region", "share", "inputPsnr", ...}).
py::list compareRegions(const std::string& out, const std::string& ref, const std::string& input,
                        const py::object& frames, const std::string& toneMap) {
    std::vector<int64_t> list = py::isinstance<py::str>(frames)
                                    ? parseFrameRange(frames.cast<std::string>())
                                    : frames.cast<std::vector<int64_t>>();
    eval::RegionStats stats;
    {
        py::gil_scoped_release unlocked;
        stats =
            eval::compareRegions(session()->registry, out, ref, input, list, toneMapArg(toneMap));
    }
    const nlohmann::json j = eval::regionsToJson(stats);
    py::list rows;
    for (const auto& [name, values] : j.items()) {
        py::dict row = fromJson(values.dump());
        row["region"] = name;
        rows.append(row);
    }
    return rows;
}

py::dict metricsRecord(const eval::FrameMetrics& m) {
    py::dict row;
    row["relMse"] = m.relMse;
    row["psnr"] = m.psnr;
    row["ssim"] = m.ssim;
    row["speckles"] = m.speckles;
    row["nonFiniteOutput"] = m.nonFiniteOutput;
    row["nonFiniteReference"] = m.nonFiniteReference;
    return row;
}

py::dict compareImages(const py::array& out, const py::array& ref, const std::string& toneMap) {
    const Image o = imageFromArray(out, "output"), r = imageFromArray(ref, "reference");
    if (o.extent() != r.extent()) throw Error("output and reference differ in size");
    return metricsRecord(eval::compareImages(o, r, toneMapArg(toneMap)));
}

void scenegen(const std::string& dir, int width, int height, int frames, int spp, int seed,
              int firstFrame) {
    scenegen::SceneOptions o;
    o.width = width;
    o.height = height;
    o.frames = frames;
    o.referenceSpp = spp;
    o.seed = uint32_t(seed);
    o.firstFrame = firstFrame;
    py::gil_scoped_release unlocked;
    scenegen::writeSequence(o, dir);
}

}  // namespace

void bindEval(py::module_& m) {
    m.def("compare", &compare, py::arg("output"), py::arg("reference"),
          py::arg("frames") = py::none(), py::arg("tonemap") = "reinhard", py::arg("layer") = "",
          py::arg("ref_layer") = "",
          "`kestrel compare --json` as a dict: 'frames' (records per frame) and 'mean'");
    m.def("compare_regions", &compareRegions, py::arg("output"), py::arg("reference"),
          py::arg("input"), py::arg("frames"), py::arg("tonemap") = "reinhard",
          "`kestrel compare --regions`: one record per region of the input's G-buffer");
    m.def("compare_images", &compareImages, py::arg("output"), py::arg("reference"),
          py::arg("tonemap") = "reinhard",
          "relMSE, PSNR, SSIM, speckles of two (height, width, 3+) arrays");
    m.def(
        "read_exr",
        [](const std::string& path, const std::string& layer) {
            return copyToArray(eval::readExrRgb(path, layer).view());
        },
        py::arg("path"), py::arg("layer") = "", "R, G, B of an EXR file as (height, width, 3)");
    m.def("scenegen", &scenegen, py::arg("out_dir"), py::arg("width") = 160, py::arg("height") = 90,
          py::arg("frames") = 8, py::arg("spp") = 64, py::arg("seed") = 1,
          py::arg("first_frame") = 1,
          "Writes the built-in room scene (`kestrel scenegen`): noisy/, ref/ EXR sequences");
}

}  // namespace kestrel::python
