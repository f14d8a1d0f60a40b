"""The examples under examples/python run, on a tiny generated scene."""
import os
import subprocess
import sys

from conftest import SOURCE


def test_sweep_writes_a_plot(tmp_path):
    png = tmp_path / "sweep.png"
    script = SOURCE / "examples" / "python" / "sweep_svgf.py"
    p = subprocess.run([sys.executable, str(script), "--size", "48x27", "--frames", "1-3",
                        "--values", "2,8", "--out", str(png)],
                       capture_output=True, text=True, timeout=120, env=os.environ.copy())
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("relMSE") == 2
    data = png.read_bytes()
    assert data.startswith(b"\x89PNG") and len(data) > 5000
