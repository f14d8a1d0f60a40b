#!/usr/bin/env bash
# The main job: set up, build, and run SVGF (graphs/svgf.json) on the built-in scene.
# Extra arguments go to `kestrel run`, e.g. scripts/demo.sh --input shot/frame_####.exr
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec build/bin/kestrel run graphs/svgf.json "$@"
