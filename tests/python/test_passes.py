"""Frames fed from numpy (ArraySource) and pass types written in Python, used by JSON graphs
loaded from Python; their errors name the pass and frame."""
import itertools
import json

import numpy as np
import pytest

import kestrel
from conftest import SVGF, in_memory

_ids = itertools.count()


def unique(name):
    """Type names are process-wide (one registry): each test registers its own."""
    return f"{name}{next(_ids)}"


def graph_file(tmp_path, passes, edges, outputs):
    path = tmp_path / "g.json"
    path.write_text(json.dumps({"kestrel": 1, "name": "py", "passes": passes,
                                "edges": edges, "outputs": outputs}))
    return str(path)


def gain_class(type_name):
    class Gain:
        type = type_name
        description = "multiplies its input by gain"
        inputs = {"color": "float3"}
        outputs = {"color": "float3"}
        params = {"gain": {"default": 2.0, "min": 0.0, "max": 8.0}}
        calls = []

        def __init__(self, params):
            self.gain = params["gain"]

        def execute(self, frame, inputs, outputs):
            Gain.calls.append(frame["frame"])
            for src, dst in zip(inputs["color"], outputs["color"]):
                np.multiply(src, self.gain, out=dst)
    return Gain


def test_array_source_feeds_a_python_pass(tmp_path):
    feed, gain = unique("Feed"), unique("Gain")
    src = kestrel.ArraySource(feed, {"color": "float3", "id": "int32"})
    rng = np.random.default_rng(1)
    frames = {f: rng.random((5, 7, 3), dtype=np.float32) for f in (1, 2, 3)}
    for f, a in frames.items():
        src.set_frame(f, {"color": a, "id": np.full((5, 7), f, np.int32)})
    assert src.frames == [1, 2, 3]
    Gain = gain_class(gain)
    kestrel.register_pass(Gain)
    g = kestrel.load_graph(graph_file(
        tmp_path, [{"name": "in", "type": feed},
                   {"name": "g", "type": gain, "params": {"gain": 3.0}}],
        [{"from": "in.color", "to": "g.color"}], ["g.color", "in.id"]))
    c = g.compile(first_frame=1)
    assert c.source_frames == [1, 2, 3]
    seen = {}
    run = kestrel.run(c, progress=lambda fr: seen.__setitem__(fr.frame, fr.output("g.color")))
    assert Gain.calls == [1, 2, 3]
    for f, a in frames.items():
        np.testing.assert_allclose(seen[f], a * 3, rtol=1e-6)
    assert (run.output("in.id") == 3).all()
    types = {t["type"]: t for t in kestrel.pass_types()}
    assert types[gain]["params"][0]["max"] == 8.0 and types[gain]["module"] == "python"


def test_array_source_checks_what_it_is_given():
    src = kestrel.ArraySource(unique("Checked"), {"color": "float3", "depth": "float"})
    ok = {"color": np.zeros((4, 6, 3), np.float32), "depth": np.zeros((4, 6), np.float32)}
    src.set_frame(1, ok)
    cases = [
        ({**ok, "color": np.zeros((4, 6, 4), np.float32)}, "expected shape \\(height, width, 3\\)"),
        ({**ok, "depth": np.zeros((4, 6), np.int32)}, "expected a float array"),
        ({**ok, "depth": np.zeros((4, 5), np.float32)}, "depth is 5x4, the other outputs 6x4"),
        ({"color": ok["color"]}, "no array given for output 'depth'"),
        ({**ok, "normal": ok["color"]}, "no output named 'normal'"),
    ]
    for arrays, message in cases:
        with pytest.raises(kestrel.Error, match=message):
            src.set_frame(2, arrays)
    assert src.frames == [1]
    src.set_frame(3, {"color": np.zeros((2, 2, 3)), "depth": np.zeros((2, 2), np.float64)})
    assert src.frames == [1, 3]
    with pytest.raises(kestrel.Error, match="unknown format 'float5'"):
        kestrel.ArraySource(unique("Bad"), {"color": "float5"})


def test_python_pass_errors_name_the_pass_and_frame(tmp_path):
    feed, bad = unique("Feed"), unique("Raising")
    src = kestrel.ArraySource(feed, {"color": "float3"})
    for f in (1, 2):
        src.set_frame(f, {"color": np.ones((3, 3, 3), np.float32)})

    class Raising:
        type = bad
        inputs = {"color": "float3"}
        outputs = {"color": "float3"}

        def __init__(self, params):
            pass

        def execute(self, frame, inputs, outputs):
            if frame["frame"] == 2:
                raise ValueError("negative radiance")

    kestrel.register_pass(Raising)
    path = graph_file(tmp_path, [{"name": "in", "type": feed}, {"name": "r", "type": bad}],
                      [{"from": "in.color", "to": "r.color"}], ["r.color"])
    c = kestrel.load_graph(path).compile(first_frame=1)
    with pytest.raises(kestrel.Error) as e:
        kestrel.run(c, frames="1-2")
    assert str(e.value) == f"frame 2, pass 'r' ({bad}): ValueError: negative radiance"
    # A frame the source was not given is a FrameError naming it.
    with pytest.raises(kestrel.FrameError, match="frame 5, pass 'in' .*no arrays given"):
        kestrel.run(c, frames=[5])


def test_python_pass_may_not_keep_views(tmp_path):
    feed, keeper = unique("Feed"), unique("Keeper")
    kestrel.ArraySource(feed, {"color": "float3"}).set_frame(1, {"color": np.ones((2, 2, 3))})

    class Keeper:
        type = keeper
        inputs = {"color": "float3"}
        outputs = {"color": "float3"}
        kept = []

        def __init__(self, params):
            pass

        def execute(self, frame, inputs, outputs):
            assert not inputs["color"][0].flags.writeable
            Keeper.kept.append(inputs["color"][0])

    kestrel.register_pass(Keeper)
    path = graph_file(tmp_path, [{"name": "in", "type": feed}, {"name": "k", "type": keeper}],
                      [{"from": "in.color", "to": "k.color"}], ["k.color"])
    with pytest.raises(kestrel.Error, match="pass 'k'.*kept a view"):
        kestrel.run(kestrel.load_graph(path).compile(first_frame=1))


def test_declaration_errors():
    class NoType:
        def execute(self, frame, inputs, outputs):
            pass
    with pytest.raises(kestrel.Error, match="needs a 'type'"):
        kestrel.register_pass(NoType)

    class BadParam:
        type = unique("BadParam")
        params = {"x": {"default": [1]}}

        def execute(self, frame, inputs, outputs):
            pass
    with pytest.raises(kestrel.Error, match="default must be"):
        kestrel.register_pass(BadParam)


def test_python_pass_parameter_is_validated_like_a_plugin(tmp_path):
    feed, gain = unique("Feed"), unique("Gain")
    kestrel.ArraySource(feed, {"color": "float3"})
    kestrel.register_pass(gain_class(gain))
    path = graph_file(tmp_path, [{"name": "in", "type": feed},
                                 {"name": "g", "type": gain, "params": {"gain": 9.0}}],
                      [{"from": "in.color", "to": "g.color"}], ["g.color"])
    with pytest.raises(kestrel.GraphError) as e:
        kestrel.load_graph(path).validate()
    assert e.value.diagnostics[0]["label"] == "g.gain"


def test_numpy_pass_inside_svgf(scene, tmp_path):
    """A pointwise numpy pass between SVGF's output and the writer's input."""
    gain = unique("Gain")
    Gain = gain_class(gain)
    kestrel.register_pass(Gain)
    base = kestrel.load_graph(SVGF, set=["input.path=" + scene["noisy"]])
    port = in_memory(base)
    plain = kestrel.run(base.compile(first_frame=1), frames="1-2").output(port)

    doc = json.loads(open(SVGF).read())
    graph = tmp_path / "svgf-gain.json"
    graph.write_text(json.dumps({
        "kestrel": 1, "name": "svgf-gain", "extends": SVGF, "drop": ["output"],
        "passes": [{"name": "gain", "type": gain, "params": {"gain": 0.5}}],
        "edges": [{"from": port, "to": "gain.color"}], "outputs": ["gain.color"]}))
    assert doc["name"] == "svgf"
    g = kestrel.load_graph(str(graph), set=["input.path=" + scene["noisy"]])
    out = kestrel.run(g.compile(first_frame=1), frames="1-2").output("gain.color")
    np.testing.assert_allclose(out, plain * 0.5, rtol=1e-6)


def test_graph_built_in_code_with_a_history_edge():
    """Falcor's shape: create_pass, add_edge, add_history_edge, mark_output."""
    feed, acc = unique("Feed"), unique("Accumulate")
    src = kestrel.ArraySource(feed, {"color": "float3"})
    for f in (1, 2, 3):
        src.set_frame(f, {"color": np.full((2, 3, 3), float(f), np.float32)})

    class Accumulate:
        type = acc
        inputs = {"color": "float3", "prev": {"format": "float3", "history": True}}
        outputs = {"color": "float3"}

        def __init__(self, params):
            pass

        def execute(self, frame, inputs, outputs):
            prev = inputs.get("prev")
            for c in range(3):
                cur = inputs["color"][c]
                outputs["color"][c][...] = cur if prev is None else 0.5 * (cur + prev[c])

    kestrel.register_pass(Accumulate)
    g = kestrel.Graph("built")
    g.create_pass("in", feed)
    g.create_pass("acc", acc)
    g.add_edge("in.color", "acc.color")
    g.add_history_edge("acc.color", "acc.prev")
    g.mark_output("acc.color")
    g.validate()
    seen = []
    kestrel.run(g.compile(first_frame=1),
                progress=lambda fr: seen.append(float(fr.output("acc.color")[0, 0, 0])))
    assert seen == [1.0, 1.5, 2.25]

    bad = kestrel.Graph("bad")
    bad.create_pass("x", "NoSuchPass", {"alpha": 1})
    with pytest.raises(kestrel.GraphError, match="NoSuchPass"):
        bad.validate()
    with pytest.raises(kestrel.Error, match="already"):
        bad.create_pass("x", "TAA")
    with pytest.raises(kestrel.Error, match="expected 'pass.port'"):
        bad.add_edge("x", "y.color")


def test_constructor_error_is_a_compile_finding():
    feed, bad = unique("Feed"), unique("BadInit")
    kestrel.ArraySource(feed, {"color": "float3"})

    class BadInit:
        type = bad
        inputs = {"color": "float3"}
        outputs = {"color": "float3"}

        def __init__(self, params):
            raise KeyError("oops")

        def execute(self, frame, inputs, outputs):
            pass

    kestrel.register_pass(BadInit)
    with pytest.raises(kestrel.Error, match="duplicate pass type"):
        kestrel.register_pass(BadInit)
    g = kestrel.Graph()
    g.create_pass("in", feed)
    g.create_pass("b", bad)
    g.add_edge("in.color", "b.color")
    g.mark_output("b.color")
    with pytest.raises(kestrel.GraphError) as e:
        g.compile(first_frame=1)
    assert str(e.value) == f"passes[1] (b): pass 'b' ({bad}): KeyError: 'oops'"


def test_python_source_reports_its_frames_and_size(tmp_path):
    source = unique("PySource")

    class Ramp:
        type = source
        outputs = {"color": "float3"}

        def __init__(self, params):
            pass

        def frames(self):
            return [1, 2]

        def begin_frame(self, frame):
            if frame > 2:
                raise kestrel.FrameError(f"no frame {frame} in the ramp")
            return (4, 3)  # width, height

        def execute(self, frame, inputs, outputs):
            for plane in outputs["color"]:
                plane[...] = frame["frame"] * np.arange(4, dtype=np.float32)

    kestrel.register_pass(Ramp)
    g = kestrel.Graph()
    g.create_pass("src", source)
    g.mark_output("src.color")
    c = g.compile(first_frame=1)
    assert c.source_frames == [1, 2]
    run = kestrel.run(c)
    assert [f["frame"] for f in run.frames] == [1, 2]
    img = run.output("src.color")
    assert img.shape == (3, 4, 3)
    np.testing.assert_array_equal(img[1, :, 0], [0, 2, 4, 6])
    with pytest.raises(kestrel.FrameError, match="frame 3, pass 'src'.*no frame 3 in the ramp"):
        kestrel.run(c, frames=[3])
