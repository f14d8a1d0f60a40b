// An in-memory source pass fed from numpy: kestrel.ArraySource("Feed", {"color": "Float3"})
// registers the type "Feed" whose outputs are the arrays given per frame with set_frame. Arrays
// are checked when given (names, shapes, channel counts, dtypes, one size per frame) and
// copied then, so the caller may reuse or free them.
#include <kestrel/Pass.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cstring>
#include <map>
#include <mutex>

#include "Bindings.h"

namespace py = pybind11;

namespace kestrel::python {
namespace {

struct FrameStore {
    std::string type;
    std::vector<std::pair<std::string, Format>> outputs;
    std::mutex mutex;  // set_frame may run in another thread while a run reads
    std::map<int64_t, std::map<std::string, Image>> frames;
};

std::string shapeText(const py::array& a) {
    std::string s = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
    return s + (a.ndim() == 1 ? ",)" : ")");
}

/// One output's array as a planar image, or Error saying what was expected and what was given.
Image toImage(const std::string& where, Format f, const py::array& given) {
    const int c = channelCount(f);
    const bool shapeOk =
        (given.ndim() == 2 && c == 1) || (given.ndim() == 3 && given.shape(2) == c);
    if (!shapeOk || given.shape(0) < 1 || given.shape(1) < 1)
        throw Error(where + ": expected shape (height, width" +
                    (c > 1 ? ", " + std::to_string(c) : "") + ") for " +
                    std::string(formatName(f)) + ", got " + shapeText(given));
    const char kind = given.dtype().kind();
    const bool ints = f == Format::Int32;
    if (ints ? (kind != 'i' && kind != 'u') : kind != 'f')
        throw Error(where + ": expected " + (ints ? "an integer" : "a float") + " array for " +
                    std::string(formatName(f)) + ", got dtype " +
                    py::str(given.dtype()).cast<std::string>());
    const int h = int(given.shape(0)), w = int(given.shape(1));
    Image img(w, h, f);
    if (ints) {
        auto a = py::array_t<int32_t, py::array::c_style | py::array::forcecast>::ensure(given);
        std::memcpy(img.view().ints(), a.data(), img.view().pixels() * sizeof(int32_t));
        return img;
    }
    auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(given);
    const float* src = a.data();
    for (size_t i = 0; i < img.view().pixels(); ++i)
        for (int ch = 0; ch < c; ++ch) img.channel(ch)[i] = src[i * size_t(c) + size_t(ch)];
    return img;
}

void setFrame(FrameStore& s, int64_t frame, const py::dict& arrays) {
    const std::string where = s.type + ": frame " + std::to_string(frame);
    std::map<std::string, Image> images;
    for (auto [k, v] : arrays) {
        const std::string name = py::str(k);
        auto it = std::find_if(s.outputs.begin(), s.outputs.end(),
                               [&](auto& o) { return o.first == name; });
        if (it == s.outputs.end()) throw Error(where + ": no output named '" + name + "'");
        images[name] = toImage(where + ": " + name, it->second, py::array::ensure(v));
    }
    Extent extent{};
    for (const auto& [name, format] : s.outputs) {
        auto it = images.find(name);
        if (it == images.end()) throw Error(where + ": no array given for output '" + name + "'");
        if (extent.width && it->second.extent() != extent)
            throw Error(where + ": " + name + " is " + std::to_string(it->second.width()) + "x" +
                        std::to_string(it->second.height()) + ", the other outputs " +
                        std::to_string(extent.width) + "x" + std::to_string(extent.height));
        extent = it->second.extent();
    }
    // Frames may differ in size: the executor resets history where the size changes.
    std::lock_guard lock(s.mutex);
    s.frames[frame] = std::move(images);
}

class ArraySourcePass : public Pass {
public:
    explicit ArraySourcePass(std::shared_ptr<FrameStore> store) : store_(std::move(store)) {}

    std::vector<int64_t> availableFrames() const override {
        std::lock_guard lock(store_->mutex);
        std::vector<int64_t> frames;
        for (const auto& f : store_->frames) frames.push_back(f.first);
        return frames;
    }

    std::optional<Extent> beginFrame(FrameContext& ctx) override {
        std::lock_guard lock(store_->mutex);
        if (!store_->frames.count(ctx.frameNumber))
            throw FrameError("no arrays given for this frame (" + store_->type + ".set_frame)");
        return store_->frames.at(ctx.frameNumber).begin()->second.extent();
    }

    void execute(FrameContext& ctx, PassIO& io) override {
        std::lock_guard lock(store_->mutex);
        const auto& images = store_->frames.at(ctx.frameNumber);
        for (const auto& [name, format] : store_->outputs) {
            if (!io.hasOutput(name)) continue;
            const ImageView& dst = io.output(name);
            const ImageView& src = images.at(name).view();
            for (int c = 0; c < src.channels(); ++c)
                std::memcpy(dst.channel(c), src.channel(c), src.pixels() * sizeof(float));
        }
    }

private:
    std::shared_ptr<FrameStore> store_;
};

std::shared_ptr<FrameStore> makeSource(
    const std::string& type, const std::vector<std::pair<std::string, std::string>>& outs) {
    if (outs.empty()) throw Error(type + ": an ArraySource needs at least one output");
    auto store = std::make_shared<FrameStore>();
    store->type = type;
    PassDesc desc(type, "frames given from numpy arrays (kestrel.ArraySource)");
    for (const auto& [name, formatText] : outs) {
        auto f = parseFormat(formatText);
        if (!f || *f == Format::Any)
            throw Error(type + ": output " + name + ": unknown format '" + formatText +
                        "' (float, float2, float3, float4 or int32)");
        desc.output(name, *f, "array given with set_frame");
        store->outputs.emplace_back(name, *f);
    }
    session()->registry.add(
        desc, [store](const ParamValues&) { return std::make_unique<ArraySourcePass>(store); },
        "python");
    return store;
}

}  // namespace

void bindArraySource(py::module_& m) {
    py::class_<FrameStore, std::shared_ptr<FrameStore>>(
        m, "ArraySource",
        "Registers a source pass type whose outputs are numpy arrays given per frame")
        .def(py::init([](const std::string& type, const py::dict& outputs) {
                 std::vector<std::pair<std::string, std::string>> outs;
                 for (auto [k, v] : outputs) outs.emplace_back(py::str(k), py::str(v));
                 return makeSource(type, outs);
             }),
             py::arg("type"), py::arg("outputs"))
        .def_readonly("type", &FrameStore::type)
        .def("set_frame", &setFrame, py::arg("frame"), py::arg("arrays"),
             "Checks and copies one frame's arrays: {output: (height, width[, channels])}")
        .def_property_readonly("frames", [](FrameStore& s) {
            std::lock_guard lock(s.mutex);
            std::vector<int64_t> f;
            for (const auto& e : s.frames) f.push_back(e.first);
            return f;
        });
}

}  // namespace kestrel::python
