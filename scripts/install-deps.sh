#!/usr/bin/env bash
# Installs every Debian (bookworm) package Overcast needs to build, test and run.
# Idempotent: packages already present are skipped; nothing is downloaded at build or run time.
set -euo pipefail

PKGS=(
  build-essential cmake pkg-config git
  clang libclang-rt-14-dev              # libFuzzer stage of .ci/run
  libuv1-dev libzstd-dev libxxhash-dev libcjson-dev libpng-dev libstb-dev libcmocka-dev
  libopenvdb-dev libboost-iostreams-dev # VDB shim (design.md: FindOpenVDB needs boost-iostreams)
  libglfw3-dev libepoxy-dev libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri mesa-utils-bin
  libmicrohttpd-dev                     # overcast-server's /metrics (docs/operations.md)
  prometheus curl                       # tests: promtool checks a /metrics scrape (the daemon never runs)
  haproxy openssl socat                 # tests: TLS and PROXY v2 in front of the server (only the test runs it)
  libhiredis-dev redis-server           # the shared brick store; tests start redis-server themselves
  xvfb                                  # scripts/window_fps.sh: the window's frame rate without a display
)

# Daemons that come with test packages (haproxy, prometheus, redis-server) must not start as services: a
# policy-rc.d that refuses every start is in place while they are installed (unless one is there).

missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
POLICY=/usr/sbin/policy-rc.d
OWN_POLICY=0
if [ ! -e "$POLICY" ]; then
  printf '#!/bin/sh\nexit 101\n' | $SUDO tee "$POLICY" >/dev/null
  $SUDO chmod 755 "$POLICY"
  OWN_POLICY=1
fi
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
[ "$OWN_POLICY" -eq 0 ] || $SUDO rm -f "$POLICY"
# under systemd the units were still enabled for the next boot: disable them
if [ -d /run/systemd/system ]; then
  for svc in haproxy prometheus redis-server; do $SUDO systemctl disable --now "$svc" 2>/dev/null || true; done
fi
