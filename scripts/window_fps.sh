#!/usr/bin/env bash
# The window's frame rate without a GPU: starts Xvfb on a free display, overcast-server on the
# built-in procedural planet (127.0.0.1, a free port, 1 s epochs) and overcast-view --window
# connected to it (the main job of scripts/run.sh) at 1280×720, lets it run for SECONDS (default 60),
# and prints what the viewer logs every 5 s ("window: F frames/s ..., worst frame M ms, trace WxH (1/S),
# epoch E shown (A s from its arrival to the screen), newest received N") and a summary over the run
# after the first 10 s: frames/s, the longest frame, the traced sizes, and how far the shown state
# trailed the newest received.
# Not a test: CI never times it (docs/performance.md, "The window without a GPU").
#
# usage: scripts/window_fps.sh [SECONDS] [overcast-view options, e.g. --frame-ms 0 or --size 640x360]
# env:   OC_BUILD  build directory holding bin/ (default build)
#        OC_OUT    folder for the logs (default a temporary one, removed at exit)
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_RUN=${1:-60}
[ $# -gt 0 ] && shift
case $SECONDS_RUN in '' | *[!0-9]*) echo "window_fps: SECONDS must be a whole number, got '$SECONDS_RUN'" >&2; exit 2 ;; esac
BIN=${OC_BUILD:-build}/bin
for p in overcast-server overcast-view; do
  [ -x "$BIN/$p" ] || { echo "window_fps: $BIN/$p is missing (build it, or set OC_BUILD)" >&2; exit 1; }
done
command -v Xvfb >/dev/null || { echo "window_fps: Xvfb is not installed" >&2; exit 1; }
KEEP=${OC_OUT:-}
OUT=${OC_OUT:-$(mktemp -d /tmp/oc_window_fps_XXXXXX)}
mkdir -p "$OUT"
XVFB='' SERVER='' VIEW=''
cleanup() {
  for p in $VIEW $SERVER $XVFB; do kill -TERM "$p" 2>/dev/null || true; done
  for p in $VIEW $SERVER $XVFB; do wait "$p" 2>/dev/null || true; done
  [ -n "$KEEP" ] || rm -rf "$OUT"
}
trap cleanup EXIT

# a free display: Xvfb picks it and writes its number
Xvfb -displayfd 3 -screen 0 1280x720x24 -nolisten tcp 3>"$OUT/display" 2>"$OUT/xvfb.log" &
XVFB=$!
for _ in $(seq 100); do [ -s "$OUT/display" ] && break; sleep 0.1; done
[ -s "$OUT/display" ] || { echo "window_fps: Xvfb did not start" >&2; cat "$OUT/xvfb.log" >&2; exit 1; }
export DISPLAY=:$(cat "$OUT/display")

. scripts/server_start.sh
oc_server_start "$BIN" "$OUT" || exit 1

CAMERA=45,0,2000,260,-5,60 # the built-in planet's camera (scripts/run.sh)
echo "window_fps: overcast-view --connect $ADDR --window --camera $CAMERA --size 1280x720 $* for $SECONDS_RUN s" \
  "on DISPLAY=$DISPLAY (Xvfb), $(nproc) cores"
"$BIN/overcast-view" --connect "$ADDR" --window --camera "$CAMERA" --size 1280x720 --out "$OUT" "$@" \
  >"$OUT/view.log" 2>&1 &
VIEW=$!
for _ in $(seq "$SECONDS_RUN"); do
  sleep 1
  kill -0 $VIEW 2>/dev/null || { echo "window_fps: the viewer stopped:" >&2; cat "$OUT/view.log" >&2; exit 1; }
done
grep -E "GL|llvmpipe|renderer" "$OUT/view.log" | head -3 || true
grep "window: " "$OUT/view.log" || { echo "window_fps: no frame drawn in $SECONDS_RUN s" >&2; tail -5 "$OUT/view.log" >&2; exit 1; }
# summary after the first 10 s (two lines): mean frames/s, traced sizes, the shown state's lag
grep "window: " "$OUT/view.log" | awk '
  NR > 2 {
    n++; match($0, /window: [0-9.]+ frames/); fps += substr($0, RSTART + 8, RLENGTH - 15)
    if (match($0, /worst frame [0-9]+ ms/)) { w = substr($0, RSTART + 12, RLENGTH - 15) + 0; if (w > slow) slow = w }
    match($0, /trace [0-9]+x[0-9]+ \(1\/[0-9]+\)/); sizes[substr($0, RSTART + 6, RLENGTH - 6)]++
    match($0, /epoch [0-9]+ shown/); e = substr($0, RSTART + 6, RLENGTH - 12) + 0
    match($0, /\([0-9.]+ s from/); a = substr($0, RSTART + 1, RLENGTH - 8) + 0
    match($0, /newest received [0-9]+/); nw = substr($0, RSTART + 16, RLENGTH - 16) + 0
    behind += nw - e; if (nw - e > worst) worst = nw - e; age += a
  }
  END {
    if (!n) { print "window_fps: too short a run for a summary (give more than 15 s)"; exit }
    s = ""; for (k in sizes) s = s sprintf(" %s×%d", k, sizes[k])
    printf "window_fps: %.2f frames/s (mean of %d 5-s windows after the first 10 s), worst frame %d ms; traced:%s; " \
           "shown state %.1f epochs behind the newest on average (at most %d); %.2f s from arrival to screen\n",
           fps / n, n, slow, s, behind / n, worst, age / n
  }'
