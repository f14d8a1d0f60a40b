#!/usr/bin/env python3
"""Parameter sweep of graphs/svgf.json from Python: error against time, plotted with matplotlib.

Each value of a parameter (default: the A-Trous iterations of every chain, '*.iterations=1..5',
written as `kestrel bench --sweep` takes it) is run over a sequence with `kestrel.run`; the error
of every frame against the reference is measured with the metrics of `kestrel compare`, in
memory, and the median time per frame is taken from the run. The plot (mean relMSE against median
ms per frame, one point per value) goes to a PNG.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/sweep_svgf.py \\
        --input scene/noisy/frame_####.exr --reference scene/ref/frame_####.exr --out sweep.png

Without --input it generates a small scene (kestrel.scenegen) in a temporary folder.
"""
import argparse
import pathlib
import statistics
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt  # noqa: E402

import kestrel  # noqa: E402

SVGF = pathlib.Path(__file__).resolve().parents[2] / "graphs" / "svgf.json"


def measure(graph_path, input_pattern, reference, assignment, frames):
    """One setting: (mean relMSE, median ms per frame) over the frames."""
    g = kestrel.load_graph(str(graph_path), set=["input.path=" + input_pattern, assignment])
    # What the writer would write, kept in memory instead of written.
    port = next(e["from"] for e in g.edges if e["to"].startswith("output."))
    g.mark_output(port)
    g.remove_pass("output")
    errors = []

    def progress(frame):
        ref = kestrel.read_exr(reference.replace("####", f"{frame.frame:04d}"))
        errors.append(kestrel.compare_images(frame.output(port), ref)["relMse"])

    run = kestrel.run(g.compile(first_frame=frames[0]), frames=frames, progress=progress)
    return statistics.mean(errors), statistics.median(f["ms"] for f in run.frames)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", help="noisy frames, frame_####.exr (default: a generated scene)")
    ap.add_argument("--reference", help="reference frames, frame_####.exr")
    ap.add_argument("--frames", default="1-4", help="frames to run (default 1-4)")
    ap.add_argument("--sweep", default="*.iterations=1,2,3,4,5",
                    help="PARAM=V1,V2,... as kestrel bench --sweep (default *.iterations=1,2,3,4,5)")
    ap.add_argument("--size", default="96x54", help="generated scene size (without --input)")
    ap.add_argument("--out", default="sweep.png", help="the plot")
    args = ap.parse_args()

    tmp = None
    if not args.input:
        tmp = tempfile.TemporaryDirectory()
        w, h = (int(v) for v in args.size.split("x"))
        kestrel.scenegen(tmp.name, width=w, height=h, frames=8, spp=32)
        args.input = tmp.name + "/noisy/frame_####.exr"
        args.reference = tmp.name + "/ref/frame_####.exr"
    if not args.reference:
        sys.exit("--reference is needed with --input")

    frames = [int(f) for f in args.frames.split("-")]
    frames = list(range(frames[0], frames[-1] + 1))
    param, values = args.sweep.split("=", 1)
    rows = []
    for v in values.split(","):
        err, ms = measure(SVGF, args.input, args.reference, f"{param}={v}", frames)
        rows.append({"value": v, "relMse": err, "ms": ms})
        print(f"{param}={v:<6}  relMSE {err:.5f}  {ms:.2f} ms/frame")

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot([r["ms"] for r in rows], [r["relMse"] for r in rows], "o")
    for r in rows:
        ax.annotate(f"{param}={r['value']}", (r["ms"], r["relMse"]), fontsize=8,
                    xytext=(4, 4), textcoords="offset points")
    ax.set_xlabel("median time per frame (ms)")
    ax.set_ylabel("mean relMSE against the reference")
    ax.set_title(f"svgf.json: sweep of {param}")
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
