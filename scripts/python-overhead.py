#!/usr/bin/env python3
"""What driving Kestrel from Python costs (docs/benchmarks.md, "Python"). A benchmark, not a test.

1. svgf.json over a sequence, `kestrel run` against the same run from Python (kestrel.run with a
   progress callback, writing the same EXR frames), alternated for several rounds. Per-frame cost
   = (wall of a long run - wall of a 2-frame run) / the frames between: start-up (process, plugin
   loading, compile, the first frames' allocation) cancels out.
2. What the Python side adds per frame, in one process: a run of 1x1 frames (ArraySource -> Mix)
   without a callback, with a no-op progress callback, and with one copying an output.
3. A Python pass: its per-call cost on a 1x1 image, and a 1080p pointwise pass (Mix's
   a + w (b - a) in numpy) against the C++ Mix, both fed by an ArraySource.

    PYTHONPATH=build/python /usr/bin/python3 scripts/python-overhead.py --input SCENE/noisy/frame_####.exr
"""
import argparse
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
CLI = str(ROOT / "build" / "bin" / "kestrel")
SVGF = str(ROOT / "graphs" / "svgf.json")

DRIVER = """
import statistics, sys, kestrel
graph, inp, out, frames, threads = sys.argv[1:6]
g = kestrel.load_graph(graph, set=["input.path=" + inp, "output.path=" + out])
first = int(frames.split("-")[0])
run = kestrel.run(g.compile(first_frame=first), frames=frames, threads=int(threads),
                  progress=lambda f: None)
print("median", statistics.median(f["ms"] for f in run.frames))
"""


def timed(cmd):
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    text = p.stdout + p.stderr
    m = re.search(r"median ([0-9.]+)", text)
    return wall, float(m.group(1)) if m else float("nan")


def drive(kind, inp, out, frames, threads):
    if kind == "cli":
        return timed([CLI, "run", SVGF, "--input", inp, "--output", out, "--frames", frames,
                      "--threads", str(threads)])
    return timed([sys.executable, "-c", DRIVER, SVGF, inp, out, frames, str(threads)])


def svgf_rounds(args):
    tmp = tempfile.mkdtemp()
    short, long_ = f"{args.first}-{args.first + 1}", f"{args.first}-{args.last}"
    n = args.last - args.first - 1
    print(f"svgf.json, frames {long_} against {short}, {args.threads} threads, "
          f"load {os.getloadavg()[0]:.1f}")
    print("| round | kestrel run ms/frame | Python ms/frame | ratio | engine median ms (run / Python) |")
    print("| --- | --- | --- | --- | --- |")
    ratios = []
    for r in range(args.rounds):
        cost, med = {}, {}
        for kind in (("cli", "py") if r % 2 == 0 else ("py", "cli")):
            out = f"{tmp}/{kind}/frame_####.exr"
            w2, _ = drive(kind, args.input, out, short, args.threads)
            wl, m = drive(kind, args.input, out, long_, args.threads)
            cost[kind], med[kind] = 1000 * (wl - w2) / n, m
        ratios.append(cost["py"] / cost["cli"])
        print(f"| {r + 1} | {cost['cli']:.1f} | {cost['py']:.1f} | {ratios[-1]:.3f} | "
              f"{med['cli']:.1f} / {med['py']:.1f} |")
    print(f"median ratio {statistics.median(ratios):.3f}, load {os.getloadavg()[0]:.1f}\n")


def callback_costs(args):
    import numpy as np

    import kestrel

    src = kestrel.ArraySource("BenchTiny", {"a": "float3", "b": "float3"})
    one = np.ones((1, 1, 3), np.float32)
    src.set_frame(1, {"a": one, "b": one})
    g = kestrel.Graph()
    g.create_pass("in", "BenchTiny")
    g.create_pass("mix", "Mix")
    g.add_edge("in.a", "mix.a")
    g.add_edge("in.b", "mix.b")
    g.mark_output("mix.color")
    c = g.compile(first_frame=1)
    n = 20000
    kinds = {"none": None, "no-op": lambda f: None, "copy": lambda f: f.output("mix.color")}
    best = {k: float("inf") for k in kinds}
    for _ in range(args.rounds):  # alternated; the best of the rounds
        for k, cb in kinds.items():
            t = time.perf_counter()
            kestrel.run(c, frames=[1] * n, threads=args.threads, progress=cb)
            best[k] = min(best[k], (time.perf_counter() - t) / n * 1e6)
    print(f"per frame, 1x1, {n} frames, best of {args.rounds}: " +
          ", ".join(f"{k} {v:.1f} us" for k, v in best.items()) +
          f"; a no-op callback adds {best['no-op'] - best['none']:.1f} us per frame")


def python_pass_costs(args):
    import numpy as np

    import kestrel

    class Copy:
        type = "BenchCopy"
        inputs = {"a": "float3"}
        outputs = {"color": "float3"}

        def __init__(self, params):
            pass

        def execute(self, frame, inputs, outputs):
            pass  # the call itself: views made, arguments passed, lock taken

    class PyMix:
        type = "BenchPyMix"
        inputs = {"a": "float3", "b": "float3"}
        outputs = {"color": "float3"}
        params = {"weight": 0.5}

        def __init__(self, params):
            self.w = params["weight"]

        def execute(self, frame, inputs, outputs):
            for a, b, o in zip(inputs["a"], inputs["b"], outputs["color"]):
                np.subtract(b, a, out=o)
                o *= self.w
                o += a

    kestrel.register_pass(Copy)
    kestrel.register_pass(PyMix)

    def pass_ms(w, h, frames, make):
        src = kestrel.ArraySource(f"BenchFeed{w}x{h}", {"a": "float3", "b": "float3"})
        rng = np.random.default_rng(1)
        arrays = {"a": rng.random((h, w, 3), np.float32), "b": rng.random((h, w, 3), np.float32)}
        for f in range(1, frames + 1):
            src.set_frame(f, arrays)
        out = {}
        for kind in make:
            g = kestrel.Graph()
            g.create_pass("in", src.type)
            g.create_pass("p", kind)
            g.add_edge("in.a", "p.a")
            if kind != "BenchCopy":
                g.add_edge("in.b", "p.b")
            g.mark_output("p.color")
            run = kestrel.run(g.compile(first_frame=1), threads=args.threads)
            out[kind] = statistics.median(t["ms"] for t in run.pass_times if t["pass"] == "p")
        return out

    tiny = pass_ms(1, 1, 300, ["BenchCopy", "BenchPyMix", "Mix"])
    print("1x1, 300 frames, median per call: " +
          ", ".join(f"{k} {v * 1000:.1f} us" for k, v in tiny.items()))
    big = pass_ms(1920, 1080, 12, ["BenchPyMix", "Mix"])
    print(f"1920x1080 pointwise (a + w (b - a)), median of 12 frames: Python {big['BenchPyMix']:.2f} ms, "
          f"C++ Mix {big['Mix']:.2f} ms ({big['BenchPyMix'] / big['Mix']:.1f}x)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", required=True, help="noisy frames (kestrel scenegen's noisy/)")
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--last", type=int, default=12)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--skip-svgf", action="store_true")
    args = ap.parse_args()
    if not args.skip_svgf:
        svgf_rounds(args)
    callback_costs(args)
    python_pass_costs(args)


if __name__ == "__main__":
    main()
