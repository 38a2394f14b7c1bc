#!/usr/bin/env bash
# Regenerates the measured tables of docs/numerics.md from the stability suite: runs the tests
# that report (tests/report.h) and the integrator comparison, and replaces the text between the
# "<!-- generated:NAME -->" and "<!-- /generated:NAME -->" markers. Usage: scripts/gen-numerics.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
DOC=docs/numerics.md
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

export OC_SOURCE_DIR=$PWD OC_SHARED_DIR=$PWD/../shared
for t in common_test_planet common_test_brick common_test_atmo shaders_test_optics shaders_test_optics_double common_test_render; do
  [ -x "$BUILD/tests/$t" ] || { echo "gen-numerics: $BUILD/tests/$t not built" >&2; exit 1; }
  echo "gen-numerics: running $t" >&2
  OC_REPORT_OUT=$tmp/stability.md OC_TABLE_OUT=$tmp/integrators_$t.md "$BUILD/tests/$t" >/dev/null
done
{
  echo "| suite | case | measured | bound | verdict |"
  echo "|---|---|---:|---:|---|"
  cat "$tmp/stability.md"
} >"$tmp/stability_table.md"
cp "$tmp/integrators_shaders_test_optics_double.md" "$tmp/integrators.md"

splice() { # name file
  python3 - "$DOC" "$1" "$2" <<'PY'
import sys, re
doc, name, path = sys.argv[1:]
s = open(doc).read()
body = open(path).read().rstrip() + "\n"
a, b = f"<!-- generated:{name} -->", f"<!-- /generated:{name} -->"
if a not in s or b not in s:
    sys.exit(f"gen-numerics: markers for {name} missing in {doc}")
i, j = s.index(a) + len(a), s.index(b)
open(doc, "w").write(s[:i] + "\n" + body + s[j:])
PY
}
splice stability "$tmp/stability_table.md"
splice integrators "$tmp/integrators.md"
echo "gen-numerics: updated $DOC" >&2
