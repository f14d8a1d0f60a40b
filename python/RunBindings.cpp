// Runs: a compiled graph over a sequence with the engine's SequenceRunner, the interpreter lock
// released while C++ runs, a progress callback per frame, and the results as arrays and records.
#include <kestrel/Executor.h>
#include <kestrel/FramePattern.h>
#include <kestrel/SequenceRunner.h>
#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <optional>

#include "Arrays.h"
#include "Bindings.h"
#include "Errors.h"

namespace py = pybind11;

namespace kestrel::python {
namespace {

/// A finished run: its executor holds the marked outputs of the last frame it ran.
struct RunObject {
    std::shared_ptr<CompiledObject> compiled;
    std::unique_ptr<Parallel> parallel;
    std::unique_ptr<Executor> exec;
    SequenceResult result;
};

/// What the progress callback gets: one frame's record and its outputs, readable only during
/// the callback (the executor overwrites them with the next frame).
struct FrameObject {
    FrameRecord record;
    size_t index = 0;
    const Executor* exec = nullptr;  // null once the callback has returned

    py::array output(const std::string& passPort) const {
        if (!exec)
            throw Error("frame " + std::to_string(record.frame) +
                        ": outputs are readable only inside the progress callback; copy them "
                        "there (frame.output() returns a copy)");
        return copyToArray(exec->output(passPort));
    }
};

/// Calls the progress callback with the lock held. A callback returning False (not None nor
/// another falsy value: a callback may return whatever it computed) stops the run
/// after that frame; an exception it raises ends the run and reaches the caller.
class Progress : public SequenceObserver {
public:
    explicit Progress(py::object callback) : callback_(std::move(callback)) {}
    bool stopRequested() const { return stop_; }

    void frameDone(const FrameRecord& f, size_t index, const Executor& exec) override {
        py::gil_scoped_acquire lock;
        auto frame = std::make_shared<FrameObject>(FrameObject{f, index, &exec});
        struct Expire {  // the frame's views end with the callback, even when it raises
            FrameObject& f;
            ~Expire() { f.exec = nullptr; }
        } expire{*frame};
        py::object answer = callback_(frame);
        if (answer.ptr() == Py_False) stop_ = true;  // only False: not any falsy value returned
    }

private:
    py::object callback_;
    bool stop_ = false;
};

std::vector<int64_t> frameList(const py::object& frames) {
    if (frames.is_none()) return {};
    if (py::isinstance<py::str>(frames)) return parseFrameRange(frames.cast<std::string>());
    return frames.cast<std::vector<int64_t>>();
}

struct RunArgs {
    py::object frames;
    int warmup = 0;
    bool resume = false;
    std::vector<int64_t> cuts;
    bool skipBadFrames = false;
    bool writeOutputs = true;
    int threads = 0;
    std::optional<std::pair<int, int>> size;
    py::object progress;
};

std::shared_ptr<RunObject> run(const std::shared_ptr<CompiledObject>& compiled, const RunArgs& a) {
    SequenceOptions so;
    so.frames = frameList(a.frames);
    so.warmup = a.warmup;
    so.resume = a.resume;
    so.cuts.insert(a.cuts.begin(), a.cuts.end());
    so.skipBadFrames = a.skipBadFrames;
    so.writeOutputs = a.writeOutputs;
    std::optional<Progress> progress;
    if (!a.progress.is_none()) progress.emplace(a.progress);
    // Ctrl-C (and any signal handler that raises) ends the run after the frame in progress:
    // Python runs its handlers only when it gets the lock back.
    bool signalled = false;
    so.stop = [&progress, &signalled] {
        if (progress && progress->stopRequested()) return true;
        py::gil_scoped_acquire lock;
        signalled = PyErr_CheckSignals() != 0;
        return signalled;
    };
    SequenceRunner runner(*compiled->graph, so);

    auto r = std::make_shared<RunObject>();
    r->compiled = compiled;
    r->parallel = std::make_unique<Parallel>(a.threads);
    RunInfo info;
    info.graphName = compiled->graph->desc().name;
    info.graphPath = compiled->graph->desc().sourcePath.string();
    info.kestrelVersion = KESTREL_VERSION;
    const Extent size = a.size ? Extent{a.size->first, a.size->second} : Extent{};
    r->exec = std::make_unique<Executor>(*compiled->graph, *r->parallel, info, size);
    if (compiled->running.exchange(true))
        throw Error(
            "this compiled graph is running in another thread: compile the graph again "
            "for a second run at the same time");
    struct Done {  // even when a callback raises
        std::atomic<bool>& flag;
        ~Done() { flag = false; }
    } done{compiled->running};
    {
        py::gil_scoped_release unlocked;
        r->result = runner.run(*r->exec, progress ? &*progress : nullptr);
    }
    if (signalled) throw py::error_already_set();  // the handler's exception, as raised
    if (r->result.end == SequenceEnd::Failed) throwRunError(r->result.error, r->result.frameError);
    return r;
}

py::list frameRecords(const SequenceResult& r) {
    py::list rows;
    for (const auto& f : r.frames) {
        py::dict row;
        row["frame"] = f.frame;
        row["written"] = f.written;
        row["ms"] = f.ms;
        rows.append(row);
    }
    return rows;
}

/// One row per pass per frame: {"frame", "pass", "ms"} (a long table for a DataFrame).
py::list passTimeRecords(const SequenceResult& r) {
    py::list rows;
    for (const auto& f : r.frames)
        for (const auto& t : f.passes) {
            py::dict row;
            row["frame"] = f.frame;
            row["pass"] = t.pass;
            row["ms"] = t.ms;
            rows.append(row);
        }
    return rows;
}

py::dict passRow(const FrameRecord& f) {
    py::dict row;
    for (const auto& t : f.passes) row[py::str(t.pass)] = t.ms;
    return row;
}

/// The last frame's planes of a marked output as views. A finished run's executor runs no more
/// frames, so its memory holds still; each view holds the Run (its numpy base), so the memory
/// lives as long as any view does.
py::tuple planes(const py::object& self, const std::string& passPort) {
    const RunObject& r = self.cast<const RunObject&>();
    const ImageView view = r.exec->output(passPort);
    if (!view.valid()) throw Error(passPort + ": the resource holds no image");
    const std::vector<py::ssize_t> shape{view.height(), view.width()};
    py::tuple out(size_t(view.channels()));
    for (int c = 0; c < view.channels(); ++c) {
        py::array a = view.format == Format::Int32
                          ? py::array(py::dtype::of<int32_t>(), shape, {}, view.ints(), self)
                          : py::array(py::dtype::of<float>(), shape, {}, view.channel(c), self);
        a.attr("setflags")(py::arg("write") = false);
        out[size_t(c)] = a;
    }
    return out;
}

void bindFrame(py::module_& m) {
    py::class_<FrameObject, std::shared_ptr<FrameObject>>(
        m, "Frame", "A frame as the progress callback sees it")
        .def_property_readonly("frame", [](const FrameObject& f) { return f.record.frame; })
        .def_property_readonly("index", [](const FrameObject& f) { return f.index; })
        .def_property_readonly("written", [](const FrameObject& f) { return f.record.written; })
        .def_property_readonly("ms", [](const FrameObject& f) { return f.record.ms; })
        .def_property_readonly("pass_ms", [](const FrameObject& f) { return passRow(f.record); })
        .def("output", &FrameObject::output, py::arg("pass_port"),
             "A copy of a marked output of this frame, (height, width, channels)");
}

void bindRunClass(py::module_& m) {
    py::class_<RunObject, std::shared_ptr<RunObject>>(m, "Run", "A finished run of a graph")
        .def_property_readonly("frames", [](const RunObject& r) { return frameRecords(r.result); })
        .def_property_readonly("pass_times",
                               [](const RunObject& r) { return passTimeRecords(r.result); })
        .def_property_readonly(
            "stopped", [](const RunObject& r) { return r.result.end == SequenceEnd::Stopped; })
        .def_property_readonly(
            "skipped",
            [](const RunObject& r) {
                py::list rows;
                for (const auto& s : r.result.skipped)
                    rows.append(py::dict(py::arg("frame") = s.frame, py::arg("error") = s.error));
                return rows;
            })
        .def_property_readonly("last_frame", [](const RunObject& r) { return r.result.lastFrame; })
        .def_property_readonly("outputs",
                               [](const RunObject& r) { return r.compiled->graph->desc().outputs; })
        .def_property_readonly("peak_bytes",
                               [](const RunObject& r) { return r.exec->memory().peakBytes; })
        .def(
            "output",
            [](const RunObject& r, const std::string& passPort) {
                return copyToArray(r.exec->output(passPort));
            },
            py::arg("pass_port"),
            "A copy of a marked output of the last frame run, (height, width, channels)")
        .def("planes", &planes, py::arg("pass_port"),
             "Read-only (height, width) views of each channel of a marked output of the last "
             "frame, without a copy: they keep the run's memory alive (nothing writes it again)");
}

}  // namespace

void bindRun(py::module_& m) {
    bindFrame(m);
    bindRunClass(m);
    m.def(
        "run",
        [](const std::shared_ptr<CompiledObject>& compiled, py::object frames, int warmup,
           bool resume, std::vector<int64_t> cuts, bool skipBadFrames, bool writeOutputs,
           int threads, std::optional<std::pair<int, int>> size, py::object progress) {
            return run(compiled,
                       RunArgs{std::move(frames), warmup, resume, std::move(cuts), skipBadFrames,
                               writeOutputs, threads, size, std::move(progress)});
        },
        py::arg("graph"), py::kw_only(), py::arg("frames") = py::none(), py::arg("warmup") = 0,
        py::arg("resume") = false, py::arg("cuts") = std::vector<int64_t>{},
        py::arg("skip_bad_frames") = false, py::arg("write_outputs") = true, py::arg("threads") = 0,
        py::arg("size") = py::none(), py::arg("progress") = py::none(),
        "Runs a compiled graph over frames ('1-8', a list, or None: every frame the sources "
        "list) with the engine's SequenceRunner; raises FrameError/Error as `kestrel run` fails");
}

}  // namespace kestrel::python
