#!/usr/bin/env bash
# The main job: installs what is missing, builds, starts overcast-server on the built-in procedural
# planet (127.0.0.1, a free port, 1 s epochs) and connects overcast-view to it over the wire
# protocol. With a display (DISPLAY or WAYLAND_DISPLAY) the viewer opens a window (mouse look, WASD,
# Esc quits; keys in overcast-view --help); otherwise it runs headless: it receives and verifies
# states for some epochs, renders the newest with the GL renderer through EGL (Mesa llvmpipe without
# a GPU; the CPU reference where no GL context can be made) and writes PNG frames, printing their
# paths. Extra arguments go to overcast-view (e.g. --size 1280x720 --camera 45,0,2000,250,0,60
# --epochs 20; by default 30 states: production runs behind the 1 s clock, so detail grows over the
# first tens of seconds). OC_OUT sets the output folder (default out); the server's log goes to
# $OC_OUT/server.log.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh >&2
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j"$(nproc)" --target overcast-server overcast-view >&2
OUT=${OC_OUT:-out}
mkdir -p "$OUT"
SERVER=''
trap '[ -z "$SERVER" ] || { kill -TERM $SERVER 2>/dev/null; wait $SERVER 2>/dev/null || true; }' EXIT
. scripts/server_start.sh
oc_server_start build/bin "$OUT" || exit 1
echo "run: overcast-server on $ADDR (log: $OUT/server.log)" >&2
# The main job's camera: 6 km over fair-weather cumulus at 45.5°N 4°W, looking down 15° (the
# scene's own camera, 2 km over a stretch with few clouds, stays for the benches). Test
# bench_look_main_job holds this view to cloud on >= 15 % of the frame and lit / dark cloud >= 2.
CAMERA=45.5,-4,6000,260,-15,60
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  build/bin/overcast-view --connect "$ADDR" --window --camera "$CAMERA" --size 1280x720 --out "$OUT" "$@"
else
  build/bin/overcast-view --connect "$ADDR" --headless --epochs 30 --timeout 900 --camera "$CAMERA" --out "$OUT" \
    --size 640x360 --threads "$(nproc)" "$@"
fi
