#!/usr/bin/env bash
# cluster.sh — a local Overcast cluster on loopback (docs/scale-out.md): one redis-server, N
# overcast-server front-ends sharing bricks through it (--redis), and HAProxy balancing viewers over
# them in TCP mode with the PROXY protocol (send-proxy-v2). HAProxy connects from 127.0.0.2, the one
# address the front-ends trust for PROXY headers, so overcast-ctl reaches each of them directly.
#
#   scripts/cluster.sh start [-n N] [--port P] [--dir DIR] [--bin DIR] [-- SERVER OPTIONS...]
#   scripts/cluster.sh status [--dir DIR]
#   scripts/cluster.sh stop [--dir DIR]
#
# start prints where each piece listens (viewers connect to HAProxy's port) and writes the process
# ids, ports and logs into DIR (default /tmp/overcast-cluster); stop ends them all by process id.
# Every port but --port (default 7420) is a free one the kernel picks.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
CMD=${1:-}
[ $# -gt 0 ] && shift
N=2
PORT=7420
DIR=/tmp/overcast-cluster
BIN=$ROOT/build/bin
EXTRA=()

usage() {
  sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'
  exit "${1:-0}"
}

while [ $# -gt 0 ]; do
  case $1 in
    -n) N=$2; shift 2 ;;
    --port) PORT=$2; shift 2 ;;
    --dir) DIR=$2; shift 2 ;;
    --bin) BIN=$2; shift 2 ;;
    --) shift; EXTRA=("$@"); break ;;
    -h|--help) usage 0 ;;
    *) echo "cluster.sh: unknown option $1" >&2; usage 2 ;;
  esac
done

die() { echo "cluster.sh: $*" >&2; exit 1; }

# A port nobody listens on now: the kernel's pick for port 0.
free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1]); s.close()'
}

# Waits until 127.0.0.1:$1 accepts connections, while process $2 lives (20 s at most).
wait_port() {
  for _ in $(seq 200); do
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 0
    kill -0 "$2" 2>/dev/null || return 1
    sleep 0.1
  done
  return 1
}

stop_all() {
  [ -f "$DIR/pids" ] || { echo "cluster.sh: nothing running in $DIR"; return 0; }
  while read -r name pid; do
    if kill -0 "$pid" 2>/dev/null; then
      kill -TERM "$pid" 2>/dev/null || true
      for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -KILL "$pid" 2>/dev/null || true
      echo "stopped $name (pid $pid)"
    fi
  done < <(tac "$DIR/pids")
  rm -f "$DIR/pids"
}

start_all() {
  [ "$N" -ge 1 ] 2>/dev/null || die "-n must be a positive number (got $N)"
  [ -x "$BIN/overcast-server" ] || die "no $BIN/overcast-server: build first (cmake --build build), or give --bin"
  command -v redis-server >/dev/null || die "redis-server is not installed (scripts/install-deps.sh)"
  command -v haproxy >/dev/null || die "haproxy is not installed (scripts/install-deps.sh)"
  mkdir -p "$DIR"
  [ ! -f "$DIR/pids" ] || die "$DIR holds a running cluster: scripts/cluster.sh stop --dir $DIR"
  : > "$DIR/pids"
  trap 'echo "cluster.sh: start failed; stopping what started" >&2; stop_all' ERR

  local rport
  rport=$(free_port)
  redis-server --port "$rport" --bind 127.0.0.1 --save '' --appendonly no --protected-mode yes \
    --maxmemory 256mb --maxmemory-policy allkeys-lru > "$DIR/redis.log" 2>&1 &
  echo "redis $!" >> "$DIR/pids"
  wait_port "$rport" $! || die "redis-server did not start: see $DIR/redis.log"
  echo "redis       127.0.0.1:$rport"

  local backends="" i line fport pid
  for i in $(seq "$N"); do
    "$BIN/overcast-server" --listen 127.0.0.1:0 --redis "127.0.0.1:$rport" --trusted-proxy 127.0.0.2 \
      "${EXTRA[@]}" > "$DIR/front$i.out" 2> "$DIR/front$i.log" &
    pid=$!
    echo "front$i $pid" >> "$DIR/pids"
    for _ in $(seq 600); do
      line=$(grep -m1 "listening on" "$DIR/front$i.out" 2>/dev/null || true)
      [ -n "$line" ] && break
      kill -0 "$pid" 2>/dev/null || die "front-end $i exited: see $DIR/front$i.log"
      sleep 0.1
    done
    [ -n "$line" ] || die "front-end $i did not listen within 60 s: see $DIR/front$i.log"
    fport=${line##*:}
    echo "front$i $fport" >> "$DIR/ports"
    echo "front-end $i 127.0.0.1:$fport (pid $pid, log $DIR/front$i.log)"
    backends+="    server front$i 127.0.0.1:$fport send-proxy-v2 check inter 1s fall 1 rise 2 check-send-proxy"$'\n'
  done

  cat > "$DIR/haproxy.cfg" <<EOF
global
    log stderr format short local0 info

defaults
    mode tcp
    log global
    option tcplog
    timeout connect 2s
    timeout client 10m
    timeout server 10m
    # from the address the front-ends trust (Linux routes all of 127.0.0.0/8 to the loopback)
    source 127.0.0.2
    # a front-end that died: the viewer's reconnect goes to another one
    option redispatch
    retries 3

frontend viewers
    bind 127.0.0.1:$PORT
    default_backend front_ends

backend front_ends
    balance leastconn
$backends
EOF
  haproxy -f "$DIR/haproxy.cfg" -db > "$DIR/haproxy.log" 2>&1 &
  echo "haproxy $!" >> "$DIR/pids"
  wait_port "$PORT" $! || die "haproxy did not listen on 127.0.0.1:$PORT: see $DIR/haproxy.log"
  trap - ERR
  echo "haproxy     127.0.0.1:$PORT (viewers: overcast-view --connect 127.0.0.1:$PORT; each front-end's"
  echo "            stats: build/bin/overcast-ctl --connect 127.0.0.1:PORT stats)"
  echo "stop with:  scripts/cluster.sh stop --dir $DIR"
}

case $CMD in
  start) rm -f "$DIR/ports"; start_all ;;
  stop) stop_all ;;
  status)
    [ -f "$DIR/pids" ] || { echo "no cluster in $DIR"; exit 0; }
    while read -r name pid; do
      if kill -0 "$pid" 2>/dev/null; then echo "$name pid $pid running"; else echo "$name pid $pid gone"; fi
    done < "$DIR/pids" ;;
  -h|--help|"") usage 0 ;;
  *) echo "cluster.sh: unknown command $CMD" >&2; usage 2 ;;
esac
