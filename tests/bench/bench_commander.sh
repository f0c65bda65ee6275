#!/bin/bash
# bench_commander.sh — input-to-photon latency of `vantage commander` on
# loopback (BENCHMARKS.md, "Commander"): a daemon with the demo city, the
# commander headless at 1280x720 JPEG, driven by a replayed DualShock 4
# capture whose left stick circles (every report a new input), for each
# tick rate asked. Prints the commander's --stats table per run.
#
#   tests/bench/bench_commander.sh BIN_DIR [SECONDS] [TICK_HZ...]
#
# CMDR_ARGS: more commander options (--full-size: no dynamic resolution).
set -euo pipefail
bin=${1:?usage: bench_commander.sh BIN_DIR [SECONDS] [TICK_HZ...]}
secs=${2:-15}
shift $(( $# >= 2 ? 2 : 1 ))
rates=("$@")
[ ${#rates[@]} -gt 0 ] || rates=(120 250 1000)
work=$(mktemp -d /tmp/vantage-bench-commander.XXXXXX)
port=$((7700 + RANDOM % 200))
trap 'kill $dpid 2>/dev/null || true; wait 2>/dev/null || true; rm -rf "$work"' EXIT
python3 "$(dirname "$0")/../data/pads/make_captures.py" "$work" latency
"$bin/vantaged" --port $port --unix "" --log-level warn &
dpid=$!
for i in $(seq 100); do "$bin/vantage" -p $port ping >/dev/null 2>&1 && break; sleep 0.05; done
echo "machine: $(nproc) cpus, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); $(date -u +%F)"
for hz in "${rates[@]}"; do
    printf 'tick_hz = %s\n' "$hz" > "$work/tick.conf"
    echo "== tick ${hz} Hz, ${secs} s, demo city (3,000 props), 1280x720 JPEG q80, renderer soft ${CMDR_ARGS:-}"
    "$bin/vantage" -p $port commander --replay "$work/ds4_latency_circle.hidrec" --config "$work/tick.conf" \
        --headless "$work/frames-$hz" --seconds "$secs" --stats ${CMDR_ARGS:-} 2>/dev/null
    rm -rf "$work/frames-$hz"
done
