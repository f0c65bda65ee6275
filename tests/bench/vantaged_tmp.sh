# vantaged_tmp.sh — sourced by bench scripts that drive a daemon of their
# own (bench_cycles.sh, docs_renders.sh): a temporary directory $ROOT
# removed on exit with the daemon, V (the CLI on the daemon's Unix socket
# there, no TCP) and start_daemon / stop_daemon. Needs $B (the build dir).
ROOT=$(mktemp -d /tmp/vantage-bench.XXXXXX)
PID=
cleanup() {
    if [ -n "$PID" ]; then kill "$PID" 2>/dev/null || true; wait "$PID" 2>/dev/null || true; fi
    rm -rf "$ROOT"
}
trap cleanup EXIT
V() { "$B/vantage" -s "$ROOT/s.sock" "$@"; }

start_daemon() { # start_daemon NAME [vantaged args]: data in $ROOT/data.NAME, log in $ROOT/log.NAME
    local name=$1
    shift
    "$B/vantaged" --bind "" --unix "$ROOT/s.sock" --data-dir "$ROOT/data.$name" --log-level warn "$@" \
        2>"$ROOT/log.$name" &
    PID=$!
    for _ in $(seq 400); do V ping >/dev/null 2>&1 && return; sleep 0.05; done
    echo "vantaged did not start"; cat "$ROOT/log.$name"; exit 1
}

stop_daemon() {
    kill "$PID"; wait "$PID" 2>/dev/null || true; PID=
}
