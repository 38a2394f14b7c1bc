#!/bin/sh
# truth_cases.sh OUTDIR [BENCH] — the Monte Carlo truth for the model-against-truth table
# (docs/numerics.md, "The real-time model against the truth"): sphere and slab, the sun behind,
# beside and in front, albedo 1, 0.99, 0.9, τ 0.5 … 50, at 32×18. Sphere 2048 paths per pixel,
# slab 512 (its paths are ~20× longer). About 20 minutes on 2 cores.
set -e
out=${1:?usage: truth_cases.sh OUTDIR [BENCH]}
bench=${2:-build/bin/overcast-bench}
mkdir -p "$out"
for shape in sphere slab; do
  paths=2048; [ "$shape" = slab ] && paths=512
  for sun in behind beside front; do
    for a in 1 0.99 0.9; do
      "$bench" truth --no-slab-check --size 32x18 --paths $paths --tau 0.5,1,2,5,10,20,50 --albedo $a \
        --scene tests/data/truth/${shape}_${sun}.json --save "$out/${shape}_${sun}_a$a" > "$out/${shape}_${sun}_a$a.md" 2>/dev/null
    done
  done
done
