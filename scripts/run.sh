#!/usr/bin/env bash
# The main job: installs what is missing, builds, and runs the viewer. Until overcast-server and
# the GL viewer land (issues [4/7], [5/7]) this renders the built-in analytic scene with the CPU
# reference renderer and writes PNG frames headless, printing their paths. Extra arguments go to
# overcast-view (e.g. --scene scenes/analytic_slab.json --camera 0,0,3000,90,10,60).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh >&2
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j"$(nproc)" --target overcast-view >&2
OUT=${OC_OUT:-out}
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  echo "run: a display is present, but this build has no GL window yet: writing PNG frames instead" >&2
fi
exec build/bin/overcast-view --scene scenes/analytic_sphere.json --out "$OUT" --size 640x360 --threads "$(nproc)" "$@"
