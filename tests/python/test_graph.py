"""Graphs from Python: loading, overrides, validation, compilation, exports, and errors raised
as the engine's classes with the CLI's own lines."""
import json

import pytest

import kestrel
from conftest import SOURCE, SVGF, cli, cli_errors


def test_error_classes_follow_the_engine():
    assert issubclass(kestrel.GraphError, kestrel.Error)
    assert issubclass(kestrel.FrameError, kestrel.Error)
    assert not issubclass(kestrel.GraphError, kestrel.FrameError)


def test_load_expands_groups_and_applies_overrides():
    g = kestrel.load_graph(SVGF, set=["*.sigmaL=6"])
    names = {p["name"] for p in g.passes}
    assert "input" in names and "output" in names
    inner = [p for p in g.passes if p["instance"] == "diffuse"]
    assert inner, "the diffuse group instance is expanded into its passes"
    set_ = [p for p in g.passes if p["params"].get("sigmaL") == 6]
    assert set_, "the pattern override reached the A-Trous passes"
    assert g.overrides == ["*.sigmaL=6"]
    pairs = g.set("diffuse.atrous0.sigmaL=3")
    assert pairs == [("diffuse.atrous0", "sigmaL")]
    assert next(p for p in g.passes if p["name"] == "diffuse.atrous0")["params"]["sigmaL"] == 3


def test_override_errors_match_the_cli(tmp_path):
    bad = "*.sigmaLL=6"
    with pytest.raises(kestrel.Error) as e:
        kestrel.load_graph(SVGF, set=[bad])
    assert "sigmaLL" in str(e.value)
    assert [str(e.value)] == cli_errors("graph", SVGF, "--set", bad)


def test_missing_file_is_an_error_naming_it(tmp_path):
    missing = str(tmp_path / "nope.json")
    with pytest.raises(kestrel.Error) as e:
        kestrel.load_graph(missing)
    assert missing in str(e.value)
    assert [str(e.value)] == cli_errors("validate", missing)


def test_validation_findings_are_a_graph_error_with_the_cli_lines(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({
        "kestrel": 1, "name": "bad",
        "passes": [{"name": "a", "type": "Demodulat"},
                   {"name": "t", "type": "TAA", "params": {"alpha": 7}}],
        "edges": [], "outputs": ["t.color"]}))
    g = kestrel.load_graph(str(path))
    with pytest.raises(kestrel.GraphError) as e:
        g.validate()
    lines = str(e.value).splitlines()
    assert lines == cli_errors("validate", str(path))
    assert len(e.value.diagnostics) == len(lines) >= 2
    paths = [d["path"] for d in e.value.diagnostics]
    assert "passes[0].type" in paths
    assert any(d["label"] == "t.alpha" for d in e.value.diagnostics)


def test_compile_lists_what_was_left_out_and_exports(scene):
    g = kestrel.load_graph(SVGF, set=["input.path=" + scene["noisy"]])
    g.validate()
    c = g.compile(first_frame=1)
    order = c.execution_order
    assert order[0] == "input" and "single.atrous4" in order
    left = c.left_out
    assert left and all(r["why"] in ("pruned", "elided") and r["reason"] for r in left)
    # The room is point-sampled and has no diffuse/specular split: TAA and the split's chains
    # are left out, each with its reason.
    why = {r["pass"]: r["why"] for r in left}
    assert why["taa"] == "elided" and why["diffuse.atrous0"] == "pruned"
    assert not set(r["pass"] for r in left) & set(order)
    assert c.source_frames == [1, 2, 3, 4]
    assert c.to_dot().startswith("digraph")
    provenance = json.loads(c.to_json())
    assert provenance, "provenance JSON names the live passes"
    res = {r["producer"]: r for r in c.resources}
    assert res["input.color"]["format"] == "float3"
    assert any(r["history"] for r in c.resources), "temporal passes keep history"


def test_unused_override_is_refused_as_the_cli_does(scene):
    # The room has no diffuse/specular split: the 'diffuse' chain is left out.
    over = "diffuse.sigmaL=3"
    g = kestrel.load_graph(SVGF, set=["input.path=" + scene["noisy"], over])
    with pytest.raises(kestrel.GraphError) as e:
        g.compile(first_frame=1)
    assert str(e.value).splitlines() == cli_errors(
        "graph", SVGF, "--input", scene["noisy"], "--set", over)


def test_pass_types_list_ports_and_parameters():
    types = {t["type"]: t for t in kestrel.pass_types()}
    assert "ExrLoader" in types and "TAA" in types
    taa = types["TAA"]
    assert any(p["name"] == "color" and p["kind"] == "input" for p in taa["ports"])
    alpha = next(p for p in taa["params"] if p["name"] == "alpha")
    assert alpha["type"] == "float" and alpha["min"] <= alpha["default"] <= alpha["max"]


def test_dot_equals_kestrel_graph_dot(scene, tmp_path):
    out = str(tmp_path / "frame_####.exr")
    g = kestrel.load_graph(SVGF, set=["input.path=" + scene["noisy"], "output.path=" + out])
    c = g.compile(first_frame=1)
    for flags, dot in (([], c.to_dot()), (["--all"], c.to_dot(all=True))):
        rc, text, err = cli("graph", SVGF, "--input", scene["noisy"],
                            "--set", "output.path=" + out, "--dot", *flags)
        assert rc == 0, err
        assert dot == text
    assert c.to_dot() != c.to_dot(all=True)


def test_inputs_and_outputs_as_the_cli_takes_them(scene, tmp_path):
    out = str(tmp_path / "frame_####.exr")
    g = kestrel.load_graph(SVGF, inputs=[scene["noisy"]], outputs=["output=" + out])
    params = {p["name"]: p["params"] for p in g.passes}
    assert params["input"]["path"] == scene["noisy"] and params["output"]["path"] == out
    with pytest.raises(kestrel.Error) as e:
        kestrel.load_graph(SVGF, inputs=["nope=x.exr"])
    assert "no input pass named 'nope'" in str(e.value)
    assert [str(e.value)] == cli_errors("graph", SVGF, "--input", "nope=x.exr")
    with pytest.raises(kestrel.Error) as e:
        kestrel.load_graph(SVGF, outputs=["input=y.exr"])
    assert "no output pass named 'input'" in str(e.value)


def test_to_json_round_trips_through_a_file_the_cli_reads(tmp_path):
    # A graph built in code and a flat graph file loaded with an override, saved as JSON:
    # load_graph reads back the same passes, parameters, edges and outputs, and `kestrel
    # validate` accepts the file. A graph with group instances is refused, naming one.
    built = kestrel.Graph("built")
    built.create_pass("input", "ExrLoader")
    built.create_pass("mix", "Mix", {"weight": 0.25})
    built.create_pass("output", "ExrWriter", {"path": str(tmp_path / "out" / "f_####.exr")})
    built.add_edge("input.color", "mix.a")
    built.add_edge("input.albedo", "mix.b")
    built.add_edge("mix.color", "output.color")
    built.mark_output("mix.color")
    flat = tmp_path / "flat.json"
    flat.write_text(built.to_json())
    loaded = kestrel.load_graph(str(flat), set=["mix.weight=0.75"])
    # A shipped flat graph with history edges (GAMES202's temporal accumulation).
    jbf = kestrel.load_graph(str(SOURCE / "graphs" / "games202-jbf.json"))
    assert any(e["history"] for e in jbf.edges)
    for g in (built, loaded, jbf):
        path = tmp_path / ("copy-" + g.name + ".json")
        path.write_text(g.to_json())
        back = kestrel.load_graph(str(path))
        key = lambda p: (p["name"], p["type"], json.dumps(p["params"], sort_keys=True))
        assert sorted(map(key, back.passes)) == sorted(map(key, g.passes))
        edge = lambda e: json.dumps(e, sort_keys=True)
        assert sorted(map(edge, back.edges)) == sorted(map(edge, g.edges))
        assert back.outputs == g.outputs
        code, _, err = cli("validate", str(path))
        assert code == 0, err
    assert next(p for p in loaded.passes if p["name"] == "mix")["params"]["weight"] == 0.75
    with pytest.raises(kestrel.Error, match="group instances"):
        kestrel.load_graph(SVGF).to_json()
