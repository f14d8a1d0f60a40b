"""Shared fixtures: the source tree, the CLI, and a tiny generated scene (built once per file)."""
import json
import os
import pathlib
import subprocess

import pytest

import kestrel

SOURCE = pathlib.Path(os.environ.get("KESTREL_SOURCE_DIR",
                                     pathlib.Path(__file__).resolve().parents[2]))
CLI = os.environ.get("KESTREL_CLI", str(SOURCE / "build" / "bin" / "kestrel"))
SVGF = str(SOURCE / "graphs" / "svgf.json")


@pytest.fixture(scope="session")
def scene(tmp_path_factory):
    """The built-in room at 48x27, 4 frames (1 spp + a 16-spp reference)."""
    d = tmp_path_factory.mktemp("scene")
    kestrel.scenegen(str(d), width=48, height=27, frames=4, spp=16)
    return {"dir": d, "noisy": str(d / "noisy" / "frame_####.exr"),
            "ref": str(d / "ref" / "frame_####.exr")}


def cli(*args):
    """Runs the kestrel CLI; returns (exit code, stdout, stderr lines)."""
    p = subprocess.run([CLI, *args], capture_output=True, text=True, timeout=120)
    return p.returncode, p.stdout, [line for line in p.stderr.splitlines() if line]


def cli_errors(*args):
    """The CLI's 'error: ...' lines without the prefix."""
    _, _, lines = cli(*args)
    return [line[len("error: "):] for line in lines if line.startswith("error: ")]


def sink_input(graph, sink="output"):
    """The 'pass.port' feeding a writer (what `kestrel run --reference` measures)."""
    return next(e["from"] for e in graph.edges if e["to"].startswith(sink + "."))


def in_memory(graph):
    """Marks what the writer would write and removes the writer: results stay in memory."""
    port = sink_input(graph)
    graph.mark_output(port)
    graph.remove_pass("output")
    return port


def load_json(text):
    return json.loads(text)
