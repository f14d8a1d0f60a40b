// Pass types declared in Python (docs/python.md, "Passes in Python"): a class with inputs,
// outputs and params whose execute() gets numpy views of its resources, registered by name in the
// registry every graph of the module uses. The engine sees a plain Pass: it never knows Python.
#include <kestrel/Pass.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <type_traits>
#include <vector>

#include "Bindings.h"
#include "Errors.h"
#include "PassDecl.h"

namespace py = pybind11;

namespace kestrel::python {
namespace {

py::dict paramDict(const ParamValues& values) {
    py::dict d;
    for (const auto& [name, v] : values.all())
        d[py::str(name)] = std::visit([](const auto& x) { return py::cast(x); }, v);
    return d;
}

/// (height, width) views of each plane of an image; read-only for inputs.
py::tuple planeViews(const ImageView& view, bool writable, std::vector<py::object>& made) {
    static int token;  // the views' base: numpy must not copy nor free the engine's memory
    const py::capsule owner(&token, [](void*) {});
    const int c = view.channels();
    py::tuple planes(c);
    const std::vector<py::ssize_t> shape{view.height(), view.width()};
    for (int ch = 0; ch < c; ++ch) {
        py::array a = view.format == Format::Int32
                          ? py::array(py::dtype::of<int32_t>(), shape, {}, view.ints(), owner)
                          : py::array(py::dtype::of<float>(), shape, {}, view.channel(ch), owner);
        if (!writable) a.attr("setflags")(py::arg("write") = false);
        made.push_back(a);
        planes[size_t(ch)] = a;
    }
    return planes;
}

class PythonPass : public Pass {
public:
    PythonPass(py::object instance, const PassDesc& desc)
        : instance_(std::move(instance)), desc_(desc) {}
    ~PythonPass() override {
        py::gil_scoped_acquire lock;
        instance_ = py::object();
    }

    void resolve(ResolveContext& rc) override { name_ = std::string(rc.passName()); }
    // (name_ is known after resolve: availableFrames is asked after it.)

    std::vector<int64_t> availableFrames() const override {
        py::gil_scoped_acquire lock;
        if (!py::hasattr(instance_, "frames")) return {};
        return call([&] { return instance_.attr("frames")().cast<std::vector<int64_t>>(); }, -1);
    }

    std::optional<Extent> beginFrame(FrameContext& ctx) override {
        py::gil_scoped_acquire lock;
        if (!py::hasattr(instance_, "begin_frame")) return std::nullopt;
        return call(
            [&] {
                auto wh =
                    instance_.attr("begin_frame")(ctx.frameNumber).cast<std::pair<int, int>>();
                return std::optional<Extent>(Extent{wh.first, wh.second});
            },
            ctx.frameNumber);
    }

    void execute(FrameContext& ctx, PassIO& io) override {
        py::gil_scoped_acquire lock;
        std::vector<py::object> made;
        call(
            [&] {
                py::dict inputs, outputs;
                for (const auto& p : desc_.ports) {
                    if (p.kind == PortKind::Input && io.hasInput(p.name))
                        inputs[py::str(p.name)] = planeViews(io.input(p.name), false, made);
                    if (p.kind == PortKind::Output && io.hasOutput(p.name))
                        outputs[py::str(p.name)] = planeViews(io.output(p.name), true, made);
                }
                py::dict frame;
                frame["frame"] = ctx.frameNumber;
                frame["index"] = ctx.frameIndex;
                frame["history_valid"] = ctx.historyValid;
                frame["width"] = ctx.extent.width;
                frame["height"] = ctx.extent.height;
                instance_.attr("execute")(frame, inputs, outputs);
                return 0;
            },
            ctx.frameNumber);
        // A view kept past execute would point into memory later passes reuse.
        for (const auto& a : made)
            if (a.ref_count() > 1)
                throw Error(where(ctx.frameNumber) +
                            "execute kept a view of its inputs or outputs after returning; keep "
                            "a copy instead (numpy.array(view))");
    }

private:
    /// The executor names the pass and frame of what beginFrame and execute throw; the compiler
    /// does not for availableFrames.
    std::string where(int64_t frame) const {
        return frame >= 0 ? std::string() : "pass '" + name_ + "' (" + desc_.type + "): ";
    }

    /// Runs fn; a Python exception becomes the engine's error, its first line ("ValueError:
    /// ..."); a kestrel.FrameError raised in Python stays a FrameError (a frame a source lacks).
    template <class Fn>
    std::invoke_result_t<Fn> call(Fn&& fn, int64_t frame) const {
        try {
            return fn();
        } catch (py::error_already_set& e) {
            std::string what = e.what();
            what = what.substr(0, what.find('\n'));
            if (isFrameError(e)) throw FrameError(where(frame) + what);
            throw Error(where(frame) + what);
        } catch (const py::cast_error& e) {
            throw Error(where(frame) + e.what());
        }
    }

    py::object instance_;
    const PassDesc desc_;
    std::string name_;
};

/// Declares the class's type in the registry; the class is kept alive by the module.
void registerPass(const py::object& cls) {
    PassDesc desc = declarePass(cls);
    const std::string type = desc.type;
    py::module_::import("kestrel").attr("_python_passes")[py::str(type)] = cls;
    PyObject* raw = cls.ptr();  // kept alive by kestrel._python_passes
    session()->registry.add(
        desc,
        [raw, desc](const ParamValues& values) -> std::unique_ptr<Pass> {
            py::gil_scoped_acquire lock;
            py::object instance;
            try {
                instance = py::reinterpret_borrow<py::object>(raw)(paramDict(values));
            } catch (py::error_already_set& e) {
                std::string what = e.what();
                throw Error(what.substr(0, what.find('\n')));  // the compiler names the pass
            }
            return std::make_unique<PythonPass>(std::move(instance), desc);
        },
        "python");
}

}  // namespace

void bindPythonPasses(py::module_& m) {
    m.attr("_python_passes") = py::dict();
    m.def("register_pass", &registerPass, py::arg("cls"),
          "Registers a pass type declared in Python (type, inputs, outputs, params, execute) "
          "under cls.type, for graphs loaded afterwards");
}

}  // namespace kestrel::python
