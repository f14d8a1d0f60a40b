"""Runs pytest on the given files with this interpreter, after checking it has what the tests
need: a `python3` first on PATH (pyenv, a venv) may lack Debian's numpy and pytest."""
import sys

missing = []
for module, package in (("numpy", "python3-numpy"), ("pytest", "python3-pytest")):
    try:
        __import__(module)
    except ImportError:
        missing.append((module, package))
if missing:
    names = ", ".join(m for m, _ in missing)
    packages = " ".join(p for _, p in missing)
    sys.exit(f"error: {sys.executable} has no {names}: install {packages} "
             f"(scripts/setup.sh does), or configure with -DPython3_EXECUTABLE=<an interpreter "
             f"that has them>")

import pytest  # noqa: E402

sys.exit(pytest.main(["-q", "-p", "no:cacheprovider", *sys.argv[1:]]))
