# Sourced by scripts/run.sh and scripts/window_fps.sh: oc_server_start BIN OUT starts BIN/overcast-server
# on the built-in procedural planet at 127.0.0.1 on a free port (its address in OUT/server.addr, its
# log in OUT/server.log), waits until it listens, and sets SERVER (its pid) and ADDR (HOST:PORT).
# Returns 1, the log printed, when the server stops before it listens.
oc_server_start() {
  "$1/overcast-server" --listen 127.0.0.1:0 >"$2/server.addr" 2>"$2/server.log" &
  SERVER=$!
  for _ in $(seq 100); do
    grep -q "listening on" "$2/server.addr" 2>/dev/null && break
    kill -0 "$SERVER" 2>/dev/null || { cat "$2/server.log" >&2; return 1; }
    sleep 0.1
  done
  ADDR=$(sed -n 's/^listening on //p' "$2/server.addr")
}
