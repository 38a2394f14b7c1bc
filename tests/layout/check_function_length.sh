#!/usr/bin/env bash
# Issue 20's rule: no function outside tests/ is longer than MAX lines (default 150), signature to
# closing brace. The tree's style makes this a line test: a definition starts with a line at column
# 0 (its signature, possibly continued on up to 5 lines) whose last line ends in ") {", and ends at
# the next "}" at column 0. Prints every function over the limit and fails if there is one.
# Usage: check_function_length.sh SOURCE_DIR [MAX]
set -euo pipefail
src=${1:?usage: check_function_length.sh SOURCE_DIR [MAX]}
max=${2:-150}
cd "$src"
files=$(git ls-files '*.c' '*.cpp' '*.h' '*.glsl' 2>/dev/null | grep -v '^tests/' ||
        find common proto server client tools shaders bench scenes scripts -type f \
          \( -name '*.c' -o -name '*.cpp' -o -name '*.h' -o -name '*.glsl' \) 2>/dev/null)
[ -n "$files" ] || { echo "check_function_length: no sources under $src" >&2; exit 2; }
long=$(echo "$files" | xargs awk -v max="$max" '
  FNR == 1 { infn = 0; sig = 0 }
  !infn && /^[A-Za-z_]/ && !/^(typedef|struct|enum|union)[ \t]/ && !/;[ \t]*$/ && !/=/ { sig = FNR; name = $0 }
  !infn && sig && /\)[ \t]*(const[ \t]*)?\{[ \t]*$/ && FNR - sig <= 5 { infn = 1; start = sig; sig = 0; next }
  !infn && /;[ \t]*$/ { sig = 0 }
  infn && /^\}/ { n = FNR - start + 1; if (n > max) printf "%s:%d: %d lines: %s\n", FILENAME, start, n, name; infn = 0 }
  END { }')
count=$(echo "$files" | xargs awk '
  FNR == 1 { infn = 0; sig = 0 }
  !infn && /^[A-Za-z_]/ && !/^(typedef|struct|enum|union)[ \t]/ && !/;[ \t]*$/ && !/=/ { sig = FNR }
  !infn && sig && /\)[ \t]*(const[ \t]*)?\{[ \t]*$/ && FNR - sig <= 5 { infn = 1; sig = 0; n++; next }
  !infn && /;[ \t]*$/ { sig = 0 }
  infn && /^\}/ { infn = 0 }
  END { print n + 0 }')
# A parser that found (almost) nothing would pass everything: the tree has well over 1000 functions.
[ "$count" -ge 1000 ] || { echo "check_function_length: only $count functions found; the parser is broken" >&2; exit 2; }
if [ -n "$long" ]; then
  echo "functions over $max lines outside tests/ (issue 20: split them):"
  echo "$long"
  exit 1
fi
echo "check_function_length: $count functions, none over $max lines"
