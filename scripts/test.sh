#!/usr/bin/env bash
# Installs dependencies, builds and runs the whole test suite in the three stages of the
# Conventions (design.md, CI), printing each stage's time:
#   1. gcc build (-Wall -Wextra, warnings are errors here) and every CTest test;
#   2. the same suite under ASan+UBSan (leak checking on);
#   3. clang libFuzzer: each target fuzzes for OC_FUZZ_SECONDS (60) and replays its corpus.
# OC_STAGES="1 2" runs a subset. Exit status is non-zero if any stage fails.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
JOBS=$(nproc)
STAGES=${OC_STAGES:-"1 2 3"}
FUZZ_SECONDS=${OC_FUZZ_SECONDS:-60}

bash scripts/install-deps.sh

declare -A took
run_stage() {
  local n=$1 name=$2; shift 2
  local t0=$SECONDS
  echo "=== stage $n: $name"
  "$@"
  took[$n]=$((SECONDS - t0))
  echo "=== stage $n ($name) passed in ${took[$n]} s"
}

stage_gcc() {
  cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_FLAGS=-Werror -DCMAKE_CXX_FLAGS=-Werror >/dev/null
  cmake --build build -j"$JOBS"
  ctest --test-dir build --output-on-failure -j"$JOBS"
}

stage_sanitize() {
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DOC_SANITIZE=ON >/dev/null
  cmake --build build-asan -j"$JOBS"
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
    LSAN_OPTIONS=suppressions=$ROOT/tests/lsan.supp:print_suppressions=0 \
    UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$JOBS"
}

stage_fuzz() {
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOC_FUZZ=ON -DOC_TESTS=OFF >/dev/null
  cmake --build build-fuzz -j"$JOBS"
  local any=0
  for bin in build-fuzz/bin/fuzz_*; do
    [ -x "$bin" ] || continue
    any=1
    local name corpus work
    name=$(basename "$bin" | sed 's/^fuzz_//')
    corpus=tests/fuzz/corpus/$name
    work=$(mktemp -d)
    cp -r "$corpus"/. "$work"/ 2>/dev/null || true
    echo "--- fuzz $name: ${FUZZ_SECONDS} s from $(ls "$work" | wc -l) seeds"
    "$bin" -max_total_time="$FUZZ_SECONDS" -print_final_stats=1 -close_fd_mask=3 "$work"
    echo "--- replay $name corpus"
    "$bin" -runs=0 "$corpus"
    rm -rf "$work"
  done
  [ $any -eq 1 ] || echo "no fuzz targets"
}

for s in $STAGES; do
  case $s in
    1) run_stage 1 "gcc build and tests" stage_gcc ;;
    2) run_stage 2 "ASan+UBSan suite" stage_sanitize ;;
    3) run_stage 3 "libFuzzer" stage_fuzz ;;
  esac
done
echo "=== stage times:"
for s in $STAGES; do echo "  stage $s: ${took[$s]} s"; done
