#!/bin/sh
# waste_perf.sh — issue 17's wasted work (CPU on bricks that end up empty) counted from perf's
# samples, beside the world's own per-brick timers, in one run.
#
# The world writes every interval its timers count to OCS_BRICK_TRACE (server/world.c,
# trace_interval: thread, start, end, wasted or not, on CLOCK_MONOTONIC, and for ahead's items the
# world time they come due), perf samples the same run on that clock (-k CLOCK_MONOTONIC), and each
# sample is given to the interval its thread was in. Both shares are given with and without the
# stock ahead leaves (its items due after the run's last epoch), as overcast-bench world gives them.
# The timers measure wall time on the producer threads; perf's cpu-clock samples only count while a
# thread runs, so the two disagree where threads wait or are preempted inside a brick.
#
# usage: scripts/waste_perf.sh [--bin DIR] [overcast-bench world options]
#        (default: build/bin, and --epochs 24 --budget 64)
set -eu
bin=build/bin
if [ "${1:-}" = "--bin" ]; then bin=$2; shift 2; fi
case "${1:-}" in -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;; esac
[ $# -gt 0 ] || set -- --epochs 24 --budget 64
command -v perf > /dev/null || { echo "waste_perf.sh: perf is not installed" >&2; exit 1; }
[ -x "$bin/overcast-bench" ] || { echo "waste_perf.sh: no $bin/overcast-bench (build first)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
OCS_BRICK_TRACE="$tmp/trace" perf record -q -e cpu-clock -F 999 -k CLOCK_MONOTONIC -o "$tmp/perf.data" \
  "$bin/overcast-bench" world "$@" > "$tmp/world.txt"
grep -E '^wasted work' "$tmp/world.txt" | sed 's/^/timers: /'
perf script -i "$tmp/perf.data" -F tid,time 2> /dev/null | tr -d ':' | awk '{ print $1, $2, 1, "-", "-" }' > "$tmp/events"
# the trace's fifth field: the world time an ahead item comes due ("-": a brick made for its epoch);
# its last line "now T": the items due after T are the stock ahead leaves, made for no brick of the run
now=$(awk '$1 == "now" { print $2 }' "$tmp/trace")
awk -v now="${now:-0}" '$1 != "now" { print $1, $2, 0, $4, ($5 != "-" && $5 + 0 > now + 0); print $1, $3, 2, "-", "-" }' \
  "$tmp/trace" >> "$tmp/events"
# per thread in time order: an interval opens (0), samples (1), it closes (2)
sort -k1,1n -k2,2g -k3,3n "$tmp/events" | awk '
  $1 != tid { tid = $1; open = 0 }
  $3 == 0 { open = 1; wasted = $4; stock = $5; next }
  $3 == 2 { open = 0; next }
  { if (!open) outside++; else { if (wasted == 1) waste++; else kept++; if (stock == 1) instock++ } }
  END {
    in_ = waste + kept; run = in_ - instock
    printf "perf:   %d of %d samples inside the timed intervals fell in bricks that ended up empty (%.1f %%; %.1f %% of the %d without ahead'"'"'s stock); %d samples outside them (planning, acks, the bench)\n", waste, in_, in_ ? 100 * waste / in_ : 0, run ? 100 * waste / run : 0, run, outside
  }'
