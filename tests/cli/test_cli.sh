#!/usr/bin/env bash
# Command-line contract of every program in build/bin (README, Programs): --help and --version exit
# 0; a usage error exits 2, a runtime error exits 1; errors are one line on stderr naming the cause.
set -u
BIN=$1
cd "${OC_SOURCE_DIR:-$(dirname "$0")/../..}"
pass=0
fail=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

check() { # name expected_status expected_stderr_regex -- command...
  local name=$1 want=$2 re=$3
  shift 4
  "$@" >"$tmp/out" 2>"$tmp/err"
  local got=$?
  local lines
  lines=$(wc -l <"$tmp/err")
  if [ "$got" -ne "$want" ]; then
    echo "FAIL $name: exit $got, want $want; stderr: $(head -c 300 "$tmp/err")"
    fail=$((fail + 1))
  elif [ -n "$re" ] && ! grep -Eq -- "$re" "$tmp/err"; then
    echo "FAIL $name: stderr does not match /$re/: $(head -c 300 "$tmp/err")"
    fail=$((fail + 1))
  elif [ "$want" -ne 0 ] && [ "$lines" -ne 1 ]; then
    echo "FAIL $name: error should be one line, got $lines: $(head -c 300 "$tmp/err")"
    fail=$((fail + 1))
  else
    pass=$((pass + 1))
  fi
}

for p in "$BIN"/overcast-*; do
  n=$(basename "$p")
  check "$n --help" 0 "" -- "$p" --help
  grep -q "usage: $n" "$tmp/out" || { echo "FAIL $n --help: no usage line"; fail=$((fail + 1)); }
  check "$n --version" 0 "" -- "$p" --version
  grep -Eq "^$n [0-9]+\.[0-9]+\.[0-9]+$" "$tmp/out" || { echo "FAIL $n --version: $(cat "$tmp/out")"; fail=$((fail + 1)); }
done

V=$BIN/overcast-view
check "view: unknown option" 2 "unknown or incomplete option \"--frobnicate\"" -- "$V" --frobnicate
check "view: bad size" 2 "--size: expected WxH" -- "$V" --size 12
check "view: size out of range" 2 "--size: 0x5: each side" -- "$V" --size 0x5
check "view: bad camera" 2 "camera fov 500 outside" -- "$V" --camera 0,0,100,0,0,500
check "view: bad renderer" 2 "--renderer bogus: expected gl or cpu" -- "$V" --renderer bogus
check "view: stray argument" 2 "unexpected argument" -- "$V" extra
check "view: --wait-epochs needs a server" 2 "go with --connect or --scene" -- "$V" --state "$tmp/none.ocst" --wait-epochs 3
check "view: --wait-epochs range" 2 "--wait-epochs: 0 is outside" -- "$V" --connect 127.0.0.1:1 --wait-epochs 0
check "view: bad value" 2 "^overcast-view: --budget: 0 is outside \[1, 1048576\]$" -- "$V" --connect 127.0.0.1:1 --budget 0
check "view: not a number" 2 "^overcast-view: --exposure: expected a finite number, got \"abc\"$" -- "$V" --exposure abc
check "view: bad short option" 2 "unknown or incomplete option \"-x\"" -- "$V" -x
# --help is generated from the option table (each option with its default and range), the window keys after it
check "view: --help" 0 "" -- "$V" --help
grep -Eq -- "--budget MIB .*\(default: 64; 1\.\.1048576\)" "$tmp/out" || { echo "FAIL view --help: --budget's default and range"; fail=$((fail + 1)); }
grep -Eq -- "--size WxH .*\(default: 640x360\)" "$tmp/out" || { echo "FAIL view --help: --size's default"; fail=$((fail + 1)); }
grep -Eq -- "^ *-q, --quiet" "$tmp/out" || { echo "FAIL view --help: -q not listed"; fail=$((fail + 1)); }
grep -q "^window keys:" "$tmp/out" && grep -q "F12 or P" "$tmp/out" || { echo "FAIL view --help: no window keys"; fail=$((fail + 1)); }
check "view: missing state" 1 "/nonexistent.ocst" -- "$V" --state /nonexistent.ocst --out "$tmp"
echo "garbage" >"$tmp/bad.ocst"
check "view: corrupt state" 1 "bad.ocst" -- "$V" --state "$tmp/bad.ocst" --out "$tmp"
echo '{"sources": [{"type": "sphere", "sigmat": 1}]}' >"$tmp/bad.json"
check "view: bad scene key" 1 "sigmat" -- "$V" --scene "$tmp/bad.json" --out "$tmp"
check "view: missing scene" 1 "nope.json" -- "$V" --scene "$tmp/nope.json" --out "$tmp"
check "view: procedural scene, served by the overcast-server it starts" 0 "" -- "$V" --scene scenes/planet.json --size 32x18 --renderer cpu --headless --out "$tmp/planet" -q
check "view: camera-from a non-PNG" 1 "not a PNG" -- "$V" --camera-from "$tmp/bad.json" --out "$tmp"

# A real render, a state round trip through --save-state / --state, and --camera-from.
check "view: renders" 0 "" -- "$V" --scene scenes/analytic_sphere.json --size 32x18 --out "$tmp/a" --save-state "$tmp/s.ocst" -q
[ -s "$tmp/a/frame_0000.png" ] && grep -q "frame_0000.png" "$tmp/out" || { echo "FAIL view: no frame path printed"; fail=$((fail + 1)); }
check "view: renders the saved state" 0 "" -- "$V" --state "$tmp/s.ocst" --camera-from "$tmp/a/frame_0000.png" --size 32x18 --out "$tmp/b" -q
cmp -s "$tmp/a/frame_0000.png" "$tmp/b/frame_0000.png" || { echo "FAIL view: state file + stored camera do not reproduce the frame"; fail=$((fail + 1)); }

S=$BIN/overcast-server
check "server: bad --listen" 2 "--listen: expected HOST:PORT" -- "$S" --listen 127.0.0.1:99999
check "server: bad --epoch-period" 2 "--epoch-period" -- "$S" --epoch-period -1
check "server: serving option with --check" 2 "serving options go without" -- "$S" --check --token x
check "server: bad --queue-limits" 2 "--queue-limits" -- "$S" --queue-limits 8,4
check "server: address not an IP" 1 "not an IPv4 or IPv6 address" -- "$S" --listen nohost:0 -q
check "server: --json without --inspect" 2 "--json goes with --inspect" -- "$S" --json
check "server: bad level" 2 "--level: 30 is outside" -- "$S" --export-vdb "$tmp/x.vdb" --level 30
check "server: bad region" 2 "--region: expected" -- "$S" --export-vdb "$tmp/x.vdb" --region 1,2
check "server: inspect a missing file" 1 "nope.vdb" -- "$S" --inspect "$tmp/nope.vdb"
check "server: inspect a non-VDB" 1 "bad.json" -- "$S" --inspect "$tmp/bad.json"
check "server: bad scene" 1 "sigmat" -- "$S" --scene "$tmp/bad.json" --check
check "server: checks the built-in planet" 0 "" -- "$S" --check
grep -q "procedural" "$tmp/out" || { echo "FAIL server --check: no source listed"; fail=$((fail + 1)); }
check "server: checks the Disney scene" 0 "" -- "$S" --scene scenes/disney_cloud.json --check -q
check "server: inspects the Disney cloud (json)" 0 "" -- "$S" --inspect ../shared/data/wdas_cloud_sixteenth.vdb --json
grep -q "415642" "$tmp/out" || { echo "FAIL server --inspect: active voxel count missing"; fail=$((fail + 1)); }
check "server: --camera without --save-state" 2 "--camera goes with --save-state" -- "$S" --check --camera 0,0,1000,0,0,60
check "server: bad camera" 2 "--camera: " -- "$S" --save-state "$tmp/p.ocst" --camera 0,0,1000,0,0
check "server: bad viewport" 2 "--viewport: expected WxH" -- "$S" --save-state "$tmp/p.ocst" --viewport 0x10
check "server: plans a state offline" 0 "" -- "$S" --scene scenes/analytic_sphere.json --save-state "$tmp/p.ocst" --epochs 3 --budget 4 --viewport 160x90 -q
check "view: renders the server's state" 0 "" -- "$V" --state "$tmp/p.ocst" --size 32x18 --out "$tmp/c" -q

# overcast-server's options are one table (server/server_config.c): --help is generated from it, one
# row per option with its default and range; the serving limits are range-checked like the others;
# a non-loopback --listen needs --token or --insecure.
"$S" --help >"$tmp/help" 2>&1
for o in listen token control-token insecure metrics-listen audit-log trusted-proxy epoch-period max-viewers max-budget total-budget cache linger max-lingering \
  linger-budget max-per-address handshake-rate idle-timeout stall-timeout queue-limits zstd-level send-buffer \
  no-deltas check inspect json export-vdb region level save-state camera epochs budget viewport scene time \
  threads quiet help version; do
  grep -Eq "^  (-q, )?--$o( |$)" "$tmp/help" || { echo "FAIL server --help: --$o not listed"; fail=$((fail + 1)); }
done
for o in max-per-address handshake-rate max-lingering linger-budget max-budget max-viewers queue-limits; do
  # the row and its continuation lines
  awk -v o="--$o" '$1 == o { p = 1; print; next } p && /^    / { print; next } { p = 0 }' "$tmp/help" | grep -q "(default:" ||
    { echo "FAIL server --help: --$o shows no default"; fail=$((fail + 1)); }
done
grep -Eq "^  --max-per-address N .*\(default: 32; 1\.\.100000\)" "$tmp/help" || { echo "FAIL server --help: --max-per-address row: $(grep -e --max-per-address "$tmp/help")"; fail=$((fail + 1)); }
LC_ALL=C tr -d '\200-\277' <"$tmp/help" | awk 'length($0) > 100 { exit 1 }' || { echo "FAIL server --help: a line over 100 columns"; fail=$((fail + 1)); }
check "server: bad --max-per-address" 2 "^overcast-server: --max-per-address: 0 is outside \[1, 100000\]$" -- "$S" --max-per-address 0
check "server: bad --handshake-rate" 2 "^overcast-server: --handshake-rate: 0.01 is outside \[0.1, 100000\]$" -- "$S" --handshake-rate 0.01
check "server: --handshake-rate not a number" 2 "^overcast-server: --handshake-rate: expected a finite number, got \"x\"$" -- "$S" --handshake-rate x
check "server: bad --max-lingering" 2 "^overcast-server: --max-lingering: -1 is outside \[0, 100000\]$" -- "$S" --max-lingering -1
check "server: --max-lingering not an integer" 2 "^overcast-server: --max-lingering: expected an integer, got \"2.5\"$" -- "$S" --max-lingering 2.5
check "server: bad --linger-budget" 2 "^overcast-server: --linger-budget: 0 is outside \[1, 16777216\]$" -- "$S" --linger-budget 0
check "server: bad --max-budget" 2 "^overcast-server: --max-budget: 0 is outside \[1, 16777216\]$" -- "$S" --max-budget 0
check "server: serving limits with --check" 2 "serving options go without" -- "$S" --check --max-per-address 4
check "server: bad --trusted-proxy" 2 "^overcast-server: --trusted-proxy: \"haproxy\" is not a numeric IPv4 or IPv6 address$" -- "$S" --trusted-proxy 127.0.0.1,haproxy
check "server: non-loopback without a token" 2 "^overcast-server: --listen 0\.0\.0\.0:0: refusing a non-loopback address without --token \(anyone who reaches it could take the whole budget\); add --token, or --insecure to allow it$" -- "$S" --listen 0.0.0.0:0 --epoch-period 0 -q
check "server: IPv6 any without a token" 2 "^overcast-server: --listen \[::\]:0: refusing a non-loopback address.*--insecure" -- "$S" --listen "[::]:0" -q
# /metrics follows the same rule (a token or --insecure off loopback); a bad --audit-log is a
# runtime error naming the file; a metrics address must be numeric like --listen's
check "server: non-loopback metrics without a token" 2 "^overcast-server: --metrics-listen 0\.0\.0\.0:0: refusing a non-loopback address without a token .*--insecure to allow it$" -- "$S" --metrics-listen 0.0.0.0:0 --epoch-period 0 -q
check "server: bad --metrics-listen" 2 "--metrics-listen: expected HOST:PORT" -- "$S" --metrics-listen 127.0.0.1:x
check "server: --metrics-listen with --check" 2 "serving options go without" -- "$S" --check --metrics-listen 0
check "server: audit log cannot be opened" 1 "^overcast-server: --audit-log $tmp/nodir/audit\.log: cannot open it for appending: No such file or directory$" -- "$S" --listen 127.0.0.1:0 --audit-log "$tmp/nodir/audit.log" -q
check "server: metrics address not an IP" 1 "--metrics-listen: \"nohost\" is not an IPv4 or IPv6 address" -- "$S" --listen 127.0.0.1:0 --metrics-listen nohost:0 --scene scenes/analytic_sphere.json -q
# --insecure starts it: wait (generously) for "listening on", then SIGTERM exits 0
"$S" --listen 0.0.0.0:0 --insecure --epoch-period 0 -q >"$tmp/srv.out" 2>"$tmp/srv.err" &
spid=$!
for _ in $(seq 600); do
  grep -q "^listening on " "$tmp/srv.out" && break
  kill -0 "$spid" 2>/dev/null || break
  sleep 0.1
done
if grep -Eq "^listening on 0\.0\.0\.0:[0-9]+$" "$tmp/srv.out"; then
  pass=$((pass + 1))
else
  echo "FAIL server --insecure: no \"listening on\": $(head -c 300 "$tmp/srv.out") $(head -c 300 "$tmp/srv.err")"
  fail=$((fail + 1))
fi
kill "$spid" 2>/dev/null
wait "$spid"
sst=$?
[ "$sst" -eq 0 ] || { echo "FAIL server --insecure: exit $sst after SIGTERM, want 0"; fail=$((fail + 1)); }

B=$BIN/overcast-bench
check "bench: no command" 2 "usage" -- "$B"
# every command is listed once in the usage (a duplicated table entry printed `noise` twice)
dups=$("$B" --help 2>/dev/null | sed -n '/^commands:/,/^$/p' | awk 'NF > 1 {print $1}' | sort | uniq -d)
[ -z "$dups" ] || { echo "FAIL bench: commands listed twice: $dups"; fail=$((fail + 1)); }
check "bench: unknown command" 2 "unknown command \"frob\"" -- "$B" frob
check "bench: bad threads" 2 "--threads: expected an integer" -- "$B" render --threads 1,x
check "bench: renders" 0 "" -- "$B" render --size 16x9 --repeat 1 --threads 1,2
grep -q "identical" "$tmp/out" || { echo "FAIL bench: thread counts not reported identical"; fail=$((fail + 1)); }
check "bench: world, bad viewers" 2 "--viewers" -- "$B" world --viewers 0
check "bench: plan, bad repeat" 2 "--repeat: 0 is outside" -- "$B" plan --repeat 0
check "bench: wire, bad epochs" 2 "--epochs: 0 is outside" -- "$B" wire --epochs 0
check "bench: wire, bad level" 2 "--level: 30 is outside" -- "$B" wire --level 30
check "bench: wire, unknown option" 2 "wire: unknown or incomplete option" -- "$B" wire --bogus
check "bench: tau, bad level" 2 "--level: 30 is outside" -- "$B" tau --level 30
check "bench: tau, bad place" 2 "--at: expected LAT,LON" -- "$B" tau --at 100,0
check "bench: steps the world" 0 "" -- "$B" world --scene scenes/analytic_sphere.json --epochs 2 --budget 2 --threads 2
# issue 17: the anchor beside the world's own rate, in the same run
grep -Eq "^anchor: a scalar 6-octave fBm once per voxel over [0-9]+ of the state's bricks, [0-9]+ bricks/s per core \(the fastest of 3 passes\); the world: [0-9]+ non-empty bricks made, [0-9]+ per second of production CPU \([0-9.]+× the anchor; [0-9.]+× without the [0-9.]+ s ahead spent on content due after the last epoch\)" "$tmp/out" ||
  { echo "FAIL bench world: no anchor line: $(grep anchor "$tmp/out")"; fail=$((fail + 1)); }
check "bench: field, a small block" 0 "" -- "$B" field --levels 14 --block 2
# the digest of every node, sampled or classified by its bound: a lever on the bounds leaves it
grep -Eq "^digest \(FNV-1a of the bytes\): sampled σt [0-9a-f]{16}, τ [0-9a-f]{16}; σt of every node [0-9a-f]{16} " "$tmp/out" ||
  { echo "FAIL bench field: no digest of every node: $(grep digest "$tmp/out")"; fail=$((fail + 1)); }
check "bench: sweep, unknown option" 2 "sweep: unknown or incomplete option \"--frobnicate\"" -- "$B" sweep --frobnicate
check "bench: sweep, bad budget list" 2 "--budgets: expected a finite number, got \"x\"" -- "$B" sweep --budgets 4,x
check "bench: sweep, hardware filtering" 2 "--reconstruction hardware: not available" -- "$B" sweep --reconstruction hardware
check "bench: truth, bad tau" 2 "--tau: 0 is outside" -- "$B" truth --tau 0
# a ground map of 1 texel (or 0, the renderer's "default") fails at once, not after the epochs
check "bench: look, one-texel ground map" 2 "^overcast-bench look: --ground-map: 1 is neither -1 nor in \\[2, 4096\\]$" -- "$B" look --ground-map 1
check "bench: render, zero ground map" 2 "--ground-map: 0 is neither -1 nor in" -- "$B" render --ground-map 0
check "bench: look, ground map too large" 2 "--ground-map: 5000 is outside \\[-1, 4096\\]" -- "$B" look --ground-map 5000
check "bench: truth, bad size" 2 "--size: expected WxH" -- "$B" truth --size 12
check "bench: truth, negative air" 2 "--air-sigma: -1 is outside" -- "$B" truth --air-sigma -1
check "bench: model, seven fit numbers" 2 "--fit wants 8 comma-separated numbers" -- "$B" model --fit 1,2,3,4,5,6,7 x.txt
check "bench: model, a ninth fit number" 2 "--fit wants 8 comma-separated numbers" -- "$B" model --fit 1,2,3,4,5,6,7,8,9 x.txt
check "bench: model, bad abc" 2 "--abc wants 3 comma-separated numbers" -- "$B" model --abc 0.5,0.5,x x.txt
check "bench: model, a search with nothing to fit" 2 "none of the files is in the fitted set" -- "$B" model --search 2 tests/data/truth/sphere_beside_a0.99-tau2.txt
check "bench: model, bad oracle" 2 "--oracle: expected view or sh0..sh8, got \"sh9\"" -- "$B" model --oracle sh9 x.txt
check "bench: model, oracle and search" 2 "--oracle does not go with --search" -- "$B" model --oracle view --search 2 x.txt
check "bench: stability, odd size" 2 "--size: expected WxH with even sides" -- "$B" stability --size 33x18
check "bench: stability, bad renderer" 2 "--renderer: expected cpu, gl or cpu,gl" -- "$B" stability --renderer vulkan
check "bench: features, bad epochs" 2 "--epochs: 0 is outside" -- "$B" features --epochs 0
check "bench: features, bad renderer" 2 "--renderer: expected cpu or gl" -- "$B" features --renderer vulkan
check "bench: noise, period not a power of two" 2 "--period must be a power of two" -- "$B" noise --period 3
check "bench: noise, period above the volume" 2 "--period must be a power of two no larger than 2\\^K" -- "$B" noise --log2-size 3 --period 16
check "bench: noise, bad size" 2 "--log2-size: 9 is outside" -- "$B" noise --log2-size 9
check "bench: noise, small run" 0 "" -- "$B" noise --log2-size 4 --points 1024 --octaves 3

C=$BIN/overcast-ctl
check "ctl: --help" 0 "" -- "$C" --help
grep -q "weather PRESET" "$tmp/out" || { echo "FAIL ctl --help: commands not listed"; fail=$((fail + 1)); }
check "ctl: --version" 0 "" -- "$C" --version
grep -Eq "^overcast-ctl [0-9]+\.[0-9]+\.[0-9]+$" "$tmp/out" || { echo "FAIL ctl --version: $(cat "$tmp/out")"; fail=$((fail + 1)); }
check "ctl: no command" 2 "no command" -- "$C"
check "ctl: unknown command" 2 "unknown command \"frob\"" -- "$C" frob
check "ctl: unknown option" 2 "unknown or incomplete option \"--frobnicate\"" -- "$C" --frobnicate stats
check "ctl: bad address" 2 "--connect: expected HOST:PORT" -- "$C" --connect localhost:0 stats
check "ctl: bad preset" 2 "PRESET must be one of" -- "$C" weather hail
check "ctl: step out of range" 2 "1001 is outside" -- "$C" step 1001
check "ctl: sun without a place" 2 "sun: give" -- "$C" sun --lat 10
check "ctl: raw non-object" 2 "raw: not a JSON object" -- "$C" raw '[1]'
check "ctl: stray argument" 2 "unexpected argument \"x\"" -- "$C" stats x
check "ctl: two different tokens" 2 "--token: a token was given already" -- "$C" --control-token a --token b stats
"$C" --help | grep -q -- "--control-token TEXT" || { echo "FAIL ctl --help: --control-token not listed"; fail=$((fail + 1)); }
# --help is generated from the option table: each option with its default and range, the commands' own too
"$C" --help >"$tmp/out"
grep -Eq -- "--timeout S .*\(default: 30; 0\.01\.\.86400\)" "$tmp/out" || { echo "FAIL ctl --help: --timeout's default and range"; fail=$((fail + 1)); }
grep -Eq -- "--lat LAT .*\(-90\.\.90\)" "$tmp/out" || { echo "FAIL ctl --help: sun --lat's range"; fail=$((fail + 1)); }
check "ctl: bad value" 2 "^overcast-ctl: --timeout: 0 is outside \[0\.01, 86400\]$" -- "$C" --timeout 0 stats
check "ctl: bad value of a command's option" 2 "^overcast-ctl: --seconds: -1 is outside" -- "$C" weather storm --seconds -1
check "ctl: bad --dir" 2 "--dir: expected X,Y,Z" -- "$C" sun --dir 0,0,0
check "ctl: another command's option" 2 "weather: unknown option \"--set\"" -- "$C" weather storm --set 3
check "ctl: option after the command, bad address" 2 "--connect: expected HOST:PORT" -- "$C" stats --connect localhost:0
check "ctl: connection refused" 1 "^overcast-ctl: 127\.0\.0\.1:1: cannot connect" -- "$C" --connect 127.0.0.1:1 --timeout 5 stats

X=$BIN/overcast-stress
if [ -x "$X" ]; then
  check "stress: --help" 0 "" -- "$X" --help
  grep -q "teleport" "$tmp/out" || { echo "FAIL stress --help: paths not listed"; fail=$((fail + 1)); }
  # generated from the option table: each option with its default and range, the rule's figures
  grep -q -- "--viewers N .*(default: 5; 1\.\.1024)" "$tmp/out" || { echo "FAIL stress --help: --viewers' default and range"; fail=$((fail + 1)); }
  grep -q -- "--fault-rss-slack MIB" "$tmp/out" || { echo "FAIL stress --help: --fault-rss-slack not listed"; fail=$((fail + 1)); }
  grep -q "lateness p99 <= 50 ms" "$tmp/out" || { echo "FAIL stress --help: the ramp's rule"; fail=$((fail + 1)); }
  check "stress: --rebalance-at without a colon" 2 "--rebalance-at: give STEP:MIB" -- "$X" --rebalance-at 3
  check "stress: --detail-reference without --ramp" 2 "go with --ramp" -- "$X" --detail-reference epochs
  check "stress: unknown option" 2 "unknown or incomplete option \"--frobnicate\"" -- "$X" --frobnicate
  check "stress: stray argument" 2 "unexpected argument \"x\"" -- "$X" x
  check "stress: bad viewers" 2 "--viewers: 0 is outside" -- "$X" --viewers 0
  check "stress: bad path" 2 "--paths: unknown path \"spin\"" -- "$X" --paths orbit,spin
  check "stress: bad budget list" 2 "--budget: expected an integer" -- "$X" --budget 4,x
  check "stress: bad depth" 2 "--max-depth: 30 is outside" -- "$X" --max-depth 8,30
  check "stress: bad size" 2 "--size: expected WxH" -- "$X" --size 160
  check "stress: bad period" 2 "--epoch-period: -1 is outside" -- "$X" --epoch-period -1
  check "stress: sweep budgets alone" 2 "--sweep-budgets and --sweep-depths go together" -- "$X" --sweep-budgets 0,16
  check "stress: bad sweep depth" 2 "--sweep-depths: 22 is outside" -- "$X" --sweep-budgets 1 --sweep-depths 1,22
  check "stress: ramp stepped" 2 "--ramp needs a period" -- "$X" --ramp --epoch-period 0
  check "stress: --scene with --connect" 2 "--scene goes with --spawn" -- "$X" --connect 127.0.0.1:1 --scene x.json
  check "stress: --spawn and --connect" 2 "exclude each other" -- "$X" --spawn --connect 127.0.0.1:1
  check "stress: --server-pid alone" 2 "--server-pid goes with --connect" -- "$X" --server-pid 1
  check "stress: bad --connect" 2 "--connect: expected HOST:PORT" -- "$X" --connect localhost
  check "stress: no such server program" 1 "^overcast-stress: /nonexistent: not an executable" -- "$X" --server /nonexistent
  check "stress: unknown fault" 2 "--faults: unknown fault \"crash\"" -- "$X" --faults stall,crash
  check "stress: faults with a period" 2 "--faults needs a stepped server" -- "$X" --faults drop --epoch-period 1
  check "stress: restart with --connect" 2 "--faults restart needs a spawned server" -- "$X" --faults restart --connect 127.0.0.1:1
  check "stress: restart after the end" 2 "--restart-at 8: must come before the last step" -- "$X" --faults restart --epochs 8 --restart-at 8
  check "stress: fault option alone" 2 "go with --faults" -- "$X" --fault-every 2
  check "stress: faults with ramp" 2 "--faults goes with neither" -- "$X" --faults garbage --ramp
  check "stress: connection refused" 1 "^overcast-stress: 127\.0\.0\.1:1: cannot connect" -- "$X" --connect 127.0.0.1:1 --timeout 5
fi
check "view: --connect with --state" 2 "--connect excludes --state and --scene" -- "$V" --connect 127.0.0.1:1 --state "$tmp/s.ocst"
check "view: --step with --state" 2 "go with --connect or --scene" -- "$V" --state "$tmp/s.ocst" --step
check "view: bad --connect" 2 "--connect: expected HOST:PORT" -- "$V" --connect "[::1"
check "view: connection refused" 1 "^overcast-view: 127\.0\.0\.1:1: cannot connect" -- "$V" --connect 127.0.0.1:1 --timeout 5 --out "$tmp"

# Renderers and modes (issue [5/7]): --renderer gl|cpu, --headless through EGL, --window needs a display.
check "view: --renderer bogus" 2 "--renderer bogus: expected gl or cpu" -- "$V" --renderer bogus --headless
check "view: --window and --headless" 2 "--window and --headless exclude each other" -- "$V" --window --headless
check "view: --window with --frames" 2 "go with --headless" -- "$V" --window --frames 2
check "view: --window with the cpu renderer" 2 "--renderer cpu goes with --headless" -- "$V" --window --renderer cpu
check "view: --window without a display" 1 "^overcast-view: --window: no display" -- env -u DISPLAY -u WAYLAND_DISPLAY "$V" --window --state "$tmp/p.ocst"
check "view: --window, display unreachable" 1 "^overcast-view: --window: cannot open a window" -- env -u WAYLAND_DISPLAY DISPLAY=:97 "$V" --window --state "$tmp/p.ocst"
if "$V" --renderer gl --headless --state "$tmp/p.ocst" --size 8x8 --out "$tmp/glprobe" -q >/dev/null 2>"$tmp/glprobe.err" || [ "${OC_GL_REQUIRE:-1}" = 1 ]; then
  # CI has Mesa (llvmpipe): the GL path must work there (OC_GL_REQUIRE=0 lets a machine without GL skip it)
  check "view: gl renders headless" 0 "" -- env -u DISPLAY -u WAYLAND_DISPLAY "$V" --renderer gl --headless --state "$tmp/p.ocst" --size 64x36 --out "$tmp/g" -q
  [ -s "$tmp/g/frame_0000.png" ] && grep -q "g/frame_0000.png" "$tmp/out" || { echo "FAIL view gl: no frame written or printed"; fail=$((fail + 1)); }
  grep -aq "renderer=gl" "$tmp/g/frame_0000.png" || { echo "FAIL view gl: settings chunk does not say renderer=gl"; fail=$((fail + 1)); }
  check "view: gl is the default without a display" 0 "" -- env -u DISPLAY -u WAYLAND_DISPLAY "$V" --state "$tmp/p.ocst" --size 64x36 --out "$tmp/gd"
  grep -q "GL: " "$tmp/err" || { echo "FAIL view: the default renderer is not gl: $(head -c 300 "$tmp/err")"; fail=$((fail + 1)); }
  check "view: gl --camera-from its own frame" 0 "" -- "$V" --renderer gl --headless --state "$tmp/p.ocst" --camera-from "$tmp/g/frame_0000.png" --size 64x36 --out "$tmp/g2" -q
  cmp -s "$tmp/g/frame_0000.png" "$tmp/g2/frame_0000.png" || { echo "FAIL view gl: stored camera does not reproduce the frame"; fail=$((fail + 1)); }
  check "view: gl renders a scene, 2 jittered frames" 0 "" -- "$V" --renderer gl --headless --scene scenes/analytic_sphere.json --size 32x18 --frames 2 --jitter --out "$tmp/gj" --save-state "$tmp/gj.ocst" -q
  [ -s "$tmp/gj/frame_0001.png" ] && [ -s "$tmp/gj.ocst" ] || { echo "FAIL view gl: --frames/--save-state"; fail=$((fail + 1)); }
else
  echo "SKIP view: no GL context ($(head -c 300 "$tmp/glprobe.err"))"
fi
check "view: cpu renders headless" 0 "" -- "$V" --renderer cpu --headless --state "$tmp/p.ocst" --size 64x36 --out "$tmp/c2" -q
grep -aq "renderer=cpu" "$tmp/c2/frame_0000.png" || { echo "FAIL view cpu: settings chunk does not say renderer=cpu"; fail=$((fail + 1)); }

# overcast-view --path: frames along a recorded camera path (CPU reference, tiny images)
printf '# test path\n0 0,-0.09,3000,90,0,40\n1 0,-0.08,3000,100,0,40\n' >"$tmp/path.txt"
check "view: --path frames" 0 "" -- "$V" --scene "$OC_SOURCE_DIR/scenes/analytic_sphere.json" --path "$tmp/path.txt" --fps 2 --size 48x27 --renderer cpu --headless --out "$tmp/pathout" -q
[ "$(grep -c frame_ "$tmp/out")" -eq 3 ] || { echo "FAIL view --path: want 3 frames, got: $(cat "$tmp/out")"; fail=$((fail + 1)); }
printf '0 0,-0.09,3000,90,0,40\n0 0,-0.08,3000,90,0,40\n' >"$tmp/badpath.txt"
check "view: --path, time not increasing" 1 "badpath.txt:2: time 0 is not after" -- "$V" --scene "$OC_SOURCE_DIR/scenes/analytic_sphere.json" --path "$tmp/badpath.txt" --renderer cpu --headless
check "view: --path with --camera" 2 "--path gives the camera" -- "$V" --path "$tmp/path.txt" --camera 0,0,1,0,0,40
check "view: --record headless" 2 "--record records a window" -- "$V" --record "$tmp/rec.txt" --headless
# --hud draws the HUD into headless frames: the PNG differs from the one without
check "view: --hud" 0 "" -- "$V" --scene "$OC_SOURCE_DIR/scenes/analytic_sphere.json" --renderer cpu --headless --size 64x36 --out "$tmp/hud1" --hud -q
check "view: no --hud" 0 "" -- "$V" --scene "$OC_SOURCE_DIR/scenes/analytic_sphere.json" --renderer cpu --headless --size 64x36 --out "$tmp/hud0" -q
cmp -s "$tmp/hud1/frame_0000.png" "$tmp/hud0/frame_0000.png" && { echo "FAIL view --hud: the frame is the same as without"; fail=$((fail + 1)); }
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
