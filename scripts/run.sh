#!/usr/bin/env bash
# The main job: installs what is missing, builds, and runs server and viewer on the built-in
# procedural planet. Until the network server and the GL viewer land (issues [4/7], [5/7]) the
# server core plans and produces the viewer's state offline (overcast-server --save-state, several
# epochs, progress on stderr) and the viewer renders it with the CPU reference renderer, headless,
# writing PNG frames and printing their paths. Extra arguments go to overcast-view (e.g. --size
# 1280x720 --camera 45,0,2000,250,0,60). OC_OUT sets the output folder (default out).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh >&2
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j"$(nproc)" --target overcast-server overcast-view >&2
OUT=${OC_OUT:-out}
mkdir -p "$OUT"
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  echo "run: a display is present, but this build has no GL window yet: writing PNG frames instead" >&2
fi
CAMERA=45,0,2000,260,-5,60 # the built-in planet's camera (scenes/planet.json)
build/bin/overcast-server --save-state "$OUT/planet.ocst" --camera "$CAMERA" --epochs 10 --budget 64 \
  --viewport 640x360 >/dev/null
exec build/bin/overcast-view --state "$OUT/planet.ocst" --camera "$CAMERA" --out "$OUT" --size 640x360 \
  --threads "$(nproc)" "$@"
