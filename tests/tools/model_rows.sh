#!/usr/bin/env bash
# `overcast-bench model --rows` against what it is made of: one row per image row, whose truth
# column averages to the stored image mean, and whose model column averages to the model's image
# mean (the truth's × (1 + the mean error) of the case's table row); rows from the top, so in the
# slab's view (camera above the slab) the top row sees sky in both and the bottom row cloud, and the
# elevations fall row by row. Usage: model_rows.sh BENCH FILE
set -euo pipefail
bench=$1 file=$2
out=$("$bench" model --rows --split "$file")
echo "$out"
h=$(awk '$1 == "size" { print $3 }' "$file")
truth=$(awk '$1 == "mean" { print $2 }' "$file")
name=$(basename "$file")
err=$(echo "$out" | awk -F'|' -v n="$name" '$2 ~ n { gsub(/[ %]/, "", $7); print $7; exit }')
echo "$out" | awk -F'|' -v h="$h" -v truth="$truth" -v err="$err" '
  /^rows of / { on = 1; next }
  on && $2 ~ /^ [0-9]+ $/ {
    n++; t += $4; m += $5
    if ($8 !~ /[0-9]/ && $5 + 0 > 0) nok++
    if (n > 1 && !($3 + 0 < last)) nfall++
    last = $3 + 0
    if (n == 1) top = $4 + $5
    bottom_t = $4 + 0; bottom_m = $5 + 0
  }
  END {
    t /= n; m /= n; want = truth * (1 + err / 100)
    printf "rows %d of %d; truth rows average %.5g against the stored mean %.5g; model rows %.5g against %.5g\n", n, h, t, truth, m, want
    if (n != h) { print "FAIL: one row per image row"; exit 1 }
    if (nok) { print "FAIL: a row with cloud has no k"; exit 1 }
    if (nfall) { print "FAIL: the elevations do not fall from the top row down"; exit 1 }
    if (top != 0 || !(bottom_t > 0) || !(bottom_m > 0)) { print "FAIL: the top row is not sky or the bottom row not cloud"; exit 1 }
    if (!(t > 0) || (t - truth) / truth > 1e-3 || (truth - t) / truth > 1e-3) { print "FAIL: the truth rows"; exit 1 }
    if ((m - want) / want > 2e-3 || (want - m) / want > 2e-3) { print "FAIL: the model rows"; exit 1 }
  }'
