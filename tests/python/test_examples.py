"""The examples under examples/python run, on a tiny generated scene."""
import os
import subprocess
import sys

from conftest import CLI, SOURCE


def test_sweep_writes_a_plot(tmp_path):
    png = tmp_path / "sweep.png"
    script = SOURCE / "examples" / "python" / "sweep_svgf.py"
    p = subprocess.run([sys.executable, str(script), "--size", "48x27", "--frames", "1-3",
                        "--sweep", "*.iterations=1,4", "--out", str(png)],
                       capture_output=True, text=True, timeout=120, env=os.environ.copy())
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("relMSE") == 2
    data = png.read_bytes()
    assert data.startswith(b"\x89PNG") and len(data) > 5000


def test_numpy_pass_in_svgf_is_compared(tmp_path):
    script = SOURCE / "examples" / "python" / "numpy_pass_svgf.py"
    p = subprocess.run([sys.executable, str(script), "--size", "48x27", "--frames", "1-3",
                        "--out", str(tmp_path), "--kestrel", CLI],
                       capture_output=True, text=True, timeout=120, env=os.environ.copy())
    assert p.returncode == 0, p.stderr
    rows = [line for line in p.stdout.splitlines() if "PSNR" in line]
    assert len(rows) == 2 and rows[1].startswith("+ Unsharp")
    psnr = [float(r.split("PSNR")[1].split()[0]) for r in rows]
    assert psnr[0] != psnr[1], "the numpy pass changed the frames"
    assert len(list((tmp_path / "unsharp").glob("frame_*.exr"))) == 3
