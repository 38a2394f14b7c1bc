#!/usr/bin/env bash
# The include graph against the layering of docs/architecture.md ("Modules"):
#   shaders ◄ common ◄ proto ◄ server / client ◄ tools
# - shaders/ includes only shaders/; common/ only common/ and shaders/; proto/ adds proto/;
#   server/ adds server/ (never client/); client/ (client/gl/ too) adds client/ (never server/);
# - tools/ includes its own headers, shaders/ ones (their precision is the includer's choice) and
#   the modules' public headers only: oc.h, ocp.h, ocs.h, ocv.h;
# - only proto/ includes zstd.h;
# - client/CMakeLists.txt never links ocs_core, server/ and proto/ never oc_client or oc_gl.
# tests/ are white-box and not checked. A header not found in any module is a library's (stb, ...).
# Usage: check_includes.sh [SOURCE_ROOT]; exits 1 naming every include that goes against a rule.
set -u
root=${1:-$(dirname "$0")/../..}
cd "$root" || exit 2
mods="common shaders proto server client client/gl tools"
public="oc.h ocp.h ocs.h ocv.h"

module_of() { # folder → module (client/gl is the client's)
  case $1 in client/gl) echo client ;; *) echo "$1" ;; esac
}
allowed() { # module → modules it may include from
  case $1 in
    shaders) echo "shaders" ;;
    common) echo "shaders common" ;;
    proto) echo "shaders common proto" ;;
    server) echo "shaders common proto server" ;;
    client) echo "shaders common proto client" ;;
    tools) echo "shaders tools" ;; # and the public headers
  esac
}
declare -A where # header name → module holding it (the first folder in $mods order)
for d in $mods; do
  for h in "$d"/*.h; do
    [ -f "$h" ] || continue
    n=${h##*/}
    [ -n "${where[$n]:-}" ] || where[$n]=$(module_of "$d")
  done
done
re='^[[:space:]]*#[[:space:]]*include[[:space:]]*([<"])([^">]+)[">]'
bad=0
files=0
for dir in $mods; do
  from=$(module_of "$dir")
  ok_to=" $(allowed "$from") "
  for f in "$dir"/*.c "$dir"/*.h "$dir"/*.cpp; do
    [ -f "$f" ] || continue
    files=$((files + 1))
    line=0
    while IFS= read -r text || [ -n "$text" ]; do
      line=$((line + 1))
      [[ $text =~ $re ]] || continue
      kind=${BASH_REMATCH[1]} h=${BASH_REMATCH[2]}
      if [ "${h##*/}" = zstd.h ]; then
        [ "$from" = proto ] || { echo "$f:$line: includes zstd.h: only proto/ may (route it through a proto/ function)"; bad=$((bad + 1)); }
        continue
      fi
      [ "$kind" = '"' ] || continue  # other system headers
      [ -f "$dir/$h" ] && continue    # its own folder
      to=${where[$h]:-}
      [ -n "$to" ] || continue        # a library's header
      [[ $ok_to == *" $to "* ]] && continue
      if [ "$from" = tools ]; then
        [[ " $public " == *" $h "* ]] && continue
        echo "$f:$line: includes \"$h\" of $to/: tools include only the public headers ($public)"
      else
        echo "$f:$line: includes \"$h\" of $to/: $from/ may include only from$ok_to"
      fi
      bad=$((bad + 1))
    done <"$f"
  done
done
# The link lines agree: client/ never links the server's library, server/ and proto/ never the
# client's (nor proto/ the server's).
for rule in client:ocs_core server:oc_client server:oc_gl proto:ocs_core proto:oc_client; do
  d=${rule%%:*} lib=${rule#*:}
  if grep -nE "target_link_libraries\(.*\b$lib\b" "$d/CMakeLists.txt" >/dev/null 2>&1; then
    echo "$d/CMakeLists.txt: links $lib: $d/ may not depend on it"
    bad=$((bad + 1))
  fi
done
if [ $files -lt 50 ]; then echo "only $files source files found under $root: wrong folder?"; exit 2; fi
if [ $bad -gt 0 ]; then echo "$bad include(s) or link line(s) against the layering (docs/architecture.md, Modules)"; exit 1; fi
echo "layout: $files files, every include follows shaders ◄ common ◄ proto ◄ server/client ◄ tools"
