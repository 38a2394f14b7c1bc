#!/usr/bin/env bash
# cluster_figures.sh — the figures of docs/scale-out.md, "What is measured": the same viewers through
# scripts/cluster.sh's HAProxy against 1, 2 and 4 front-ends (one producer thread each), then from
# every front-end's stats and Redis's INFO: bricks made cluster-wide per viewer-epoch, the store's
# hit rate, Redis memory per viewer, and what a production waits for its lookup (per lookup, and
# spread over the bricks it looked up: the latency sharing adds per fetched brick).
#
#   scripts/cluster_figures.sh [--counts "1 2 4"] [--viewers V] [--paths LIST] [--budget MIB]
#                              [--seconds S] [--port P] [--dir DIR] [--bin DIR]
#
# Prints one Markdown table; each run's raw replies stay in DIR (default /tmp/overcast-figures).
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
COUNTS="1 2 4"
VIEWERS=4
PATHS=orbit,dive
BUDGET=16
SECONDS_RUN=40
PORT=7460
DIR=/tmp/overcast-figures
BIN=$ROOT/build/bin

usage() {
  sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'
  exit "${1:-0}"
}

while [ $# -gt 0 ]; do
  case $1 in
    --counts) COUNTS=$2; shift 2 ;;
    --viewers) VIEWERS=$2; shift 2 ;;
    --paths) PATHS=$2; shift 2 ;;
    --budget) BUDGET=$2; shift 2 ;;
    --seconds) SECONDS_RUN=$2; shift 2 ;;
    --port) PORT=$2; shift 2 ;;
    --dir) DIR=$2; shift 2 ;;
    --bin) BIN=$2; shift 2 ;;
    -h|--help) usage 0 ;;
    *) echo "cluster_figures.sh: unknown option $1" >&2; usage 2 ;;
  esac
done
command -v redis-cli >/dev/null || { echo "cluster_figures.sh: redis-cli is not installed (scripts/install-deps.sh)" >&2; exit 1; }
mkdir -p "$DIR"

# One run: N front-ends, the viewers through HAProxy, then everyone's figures into $DIR/N/.
run_one() {
  local n=$1 d=$DIR/$1
  rm -rf "$d" && mkdir -p "$d"
  bash "$ROOT/scripts/cluster.sh" start -n "$n" --port "$PORT" --dir "$d/cluster" --bin "$BIN" -- --threads 1 > "$d/start.txt"
  trap 'bash "$ROOT/scripts/cluster.sh" stop --dir "$d/cluster" >/dev/null' RETURN
  local rport
  rport=$(awk '/^redis /{split($2, a, ":"); print a[2]}' "$d/start.txt")
  "$BIN/overcast-stress" --connect "127.0.0.1:$PORT" --viewers "$VIEWERS" --paths "$PATHS" --share-paths \
    --budget "$BUDGET" --duration "$SECONDS_RUN" --json "$d/stress.json" > "$d/stress.txt" 2>&1 || true
  while read -r name port; do
    "$BIN/overcast-ctl" --connect "127.0.0.1:$port" stats > "$d/$name.json"
  done < "$d/cluster/ports"
  redis-cli -p "$rport" info memory > "$d/redis_memory.txt"
  redis-cli -p "$rport" info commandstats > "$d/redis_commands.txt"
  redis-cli -p "$rport" dbsize > "$d/redis_keys.txt"
}

# The row of run N from its files (python3: the replies are JSON).
row() {
  python3 - "$DIR/$1" "$1" "$VIEWERS" <<'EOF'
import glob, json, re, sys
d, n, viewers = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
made = lookups = looked = taken = wait = 0
fronts = []
for f in sorted(glob.glob(d + "/front*.json")):
    w = json.load(open(f))
    w = w.get("world", w)
    s = w.get("share", {})
    made += w["bricks_produced"]; fronts.append(w["bricks_produced"])
    looked += s.get("looked_up", 0); taken += s.get("taken", 0); lookups += s.get("lookups", 0)
    wait += s.get("wait_us", 0)
st = json.load(open(d + "/stress.json"))
states = sum(v.get("states", 0) for v in st.get("viewers", []))
mem = dict(l.strip().split(":", 1) for l in open(d + "/redis_memory.txt") if ":" in l)
used = int(mem["used_memory"]) - int(mem.get("used_memory_startup", 0))
get = re.search(r"cmdstat_get:calls=(\d+),usec=(\d+)", open(d + "/redis_commands.txt").read())
usec = int(get.group(2)) / max(1, int(get.group(1))) if get else float("nan")
keys = int(open(d + "/redis_keys.txt").read().split()[-1])
verdict = "PASS" if st.get("pass", st.get("ok", True)) else "FAIL"
print(f"| {n} | {' / '.join(str(x) for x in fronts)} | {made} | {made / max(1, states):.1f} | "
      f"{100.0 * taken / max(1, looked):.1f} % | {keys} | {used / 1048576 / viewers:.1f} MiB | {usec:.1f} µs | "
      f"{wait / 1000 / max(1, lookups):.1f} ms | {wait / max(1, looked):.1f} µs | {states} | {verdict} |")
EOF
}

for n in $COUNTS; do
  echo "cluster_figures.sh: $n front-end(s), $VIEWERS viewers ($PATHS), $BUDGET MiB, $SECONDS_RUN s" >&2
  run_one "$n"
done
echo "| front-ends | bricks made (each) | made in all | per viewer-state | store hit rate (taken / looked up) | keys in Redis | Redis memory per viewer | Redis time per GET | wait per lookup | wait per brick looked up | viewer states | checks |"
echo "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"
for n in $COUNTS; do row "$n"; done
