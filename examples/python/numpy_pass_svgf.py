#!/usr/bin/env python3
"""A new pass prototyped in numpy inside graphs/svgf.json, compared with `kestrel compare`.

The pass, "Unsharp", sharpens SVGF's output a little (unsharp mask on a 3x3 box blur, `amount`
a parameter with a range): A-Trous blurs detail, and this tries to give some back. It is put
between TAA's output and the writer by a graph that extends svgf.json, the run writes EXR frames,
and `kestrel compare` measures both graphs against the reference.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/numpy_pass_svgf.py \\
        --input scene/noisy/frame_####.exr --reference scene/ref/frame_####.exr --out out/

Without --input it generates a small scene (kestrel.scenegen) in a temporary folder.
"""
import argparse
import json
import pathlib
import subprocess
import tempfile

import numpy as np

import kestrel

ROOT = pathlib.Path(__file__).resolve().parents[2]
SVGF = ROOT / "graphs" / "svgf.json"


class Unsharp:
    type = "Unsharp"
    description = "unsharp mask: x + amount * (x - box3x3(x)), per channel"
    inputs = {"color": "float3"}
    outputs = {"color": "float3"}
    params = {"amount": {"default": 0.3, "min": 0.0, "max": 2.0,
                         "description": "how much of the detail to add back"}}

    def __init__(self, params):
        self.amount = params["amount"]

    def execute(self, frame, inputs, outputs):
        for src, dst in zip(inputs["color"], outputs["color"]):
            pad = np.pad(src, 1, mode="edge")
            h, w = src.shape
            blur = sum(pad[y:y + h, x:x + w] for y in range(3) for x in range(3)) / 9.0
            np.maximum(src + self.amount * (src - blur), 0.0, out=dst)


def graph_with_pass(folder):
    """svgf.json with Unsharp between TAA and a writer (the base writer dropped)."""
    path = pathlib.Path(folder) / "svgf-unsharp.json"
    path.write_text(json.dumps({
        "kestrel": 1, "name": "svgf-unsharp", "extends": str(SVGF), "drop": ["output"],
        "passes": [{"name": "unsharp", "type": "Unsharp"},
                   {"name": "written", "type": "ExrWriter"}],
        "edges": [{"from": "taa.color", "to": "unsharp.color"},
                  {"from": "unsharp.color", "to": "written.color"},
                  {"from": "input.alpha", "to": "written.alpha"}]}))
    return path


def run(graph, writer, input_pattern, out_pattern, frames, sets=()):
    g = kestrel.load_graph(str(graph), set=[f"input.path={input_pattern}",
                                            f"{writer}.path={out_pattern}", *sets])
    kestrel.run(g.compile(first_frame=frames[0]), frames=frames)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", help="noisy frames (default: a generated scene)")
    ap.add_argument("--reference", help="reference frames")
    ap.add_argument("--frames", default="1-4")
    ap.add_argument("--amount", type=float, default=0.3)
    ap.add_argument("--size", default="96x54", help="generated scene size (without --input)")
    ap.add_argument("--out", help="folder of the output frames (default: a temporary one)")
    ap.add_argument("--kestrel", default=str(ROOT / "build" / "bin" / "kestrel"), help="the CLI")
    args = ap.parse_args()

    tmp = tempfile.TemporaryDirectory()
    if not args.input:
        w, h = (int(v) for v in args.size.split("x"))
        kestrel.scenegen(tmp.name, width=w, height=h, frames=8, spp=32)
        args.input = tmp.name + "/noisy/frame_####.exr"
        args.reference = tmp.name + "/ref/frame_####.exr"
    out = pathlib.Path(args.out or tmp.name)
    first, last = (int(v) for v in args.frames.split("-"))
    frames = list(range(first, last + 1))

    kestrel.register_pass(Unsharp)
    plain, sharp = str(out / "svgf" / "frame_####.exr"), str(out / "unsharp" / "frame_####.exr")
    run(SVGF, "output", args.input, plain, frames)
    run(graph_with_pass(tmp.name), "written", args.input, sharp, frames,
        [f"unsharp.amount={args.amount}"])

    for name, pattern in (("svgf.json", plain), (f"+ Unsharp {args.amount}", sharp)):
        table = subprocess.run([args.kestrel, "compare", pattern, args.reference,
                                "--frames", args.frames, "--json"],
                               check=True, capture_output=True, text=True).stdout
        mean = json.loads(table)["mean"]
        print(f"{name:<16} relMSE {mean['relMse']:.5f}  PSNR {mean['psnr']:.2f} dB  "
              f"SSIM {mean['ssim']:.4f}")


if __name__ == "__main__":
    main()
