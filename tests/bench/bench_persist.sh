#!/usr/bin/env bash
# bench_persist.sh — vantaged --data-dir figures for BENCHMARKS.md:
#   1. recovery time of a 1M-entity scene, from the journal alone and from a
#      snapshot (kill -9, restart, the daemon's own "restored in N ms" line);
#   2. edit throughput per durability policy (no --data-dir, off, everysec,
#      always) with `vantage bench --test edit`, alternated, medians.
# Usage: tests/bench/bench_persist.sh [BUILD_DIR] (default build/release).
# Data goes to a directory on the disk ($BENCH_DIR, default /var/tmp).
set -euo pipefail
B=${1:-build/release}
ROOT=${BENCH_DIR:-/var/tmp}/vantage-bench-persist.$$
PORT=${PORT:-7611}
mkdir -p "$ROOT"
trap 'kill -9 $(jobs -p) 2>/dev/null || true; rm -rf "$ROOT"' EXIT

start() { # start DIR_OR_EMPTY POLICY [more args]; sets PID
    local dir=$1 pol=$2
    shift 2
    local extra=()
    [ -n "$dir" ] && extra=(--data-dir "$dir" --durability "$pol")
    "$B/vantaged" --scene empty --port $PORT --unix "" --log-level info "${extra[@]}" "$@" 2>"$ROOT/log" &
    PID=$!
    for _ in $(seq 200); do "$B/vantage" -p $PORT ping >/dev/null 2>&1 && return; sleep 0.05; done
    echo "vantaged did not start"; cat "$ROOT/log"; exit 1
}

echo "== recovery of 1,000,000 entities"
python3 - "$ROOT/m.jsonl" <<'EOF'
import sys
with open(sys.argv[1], "w") as f:
    for i in range(1_000_000):
        f.write('{"id": %d, "sphere": [%d, 0.5, %d, 0.5]}\n' % (i + 1, (i % 1000) * 2, (i // 1000) * 2))
EOF
for mode in journal snapshot; do
    rm -rf "$ROOT/d"
    # a journal-only run never reaches the compaction size; the snapshot
    # run compacts as soon as the journal passes 64 MB
    cm=$([ $mode = journal ] && echo 100000 || echo 64)
    start "$ROOT/d" everysec --compact-mb $cm
    "$B/vantage" -p $PORT import "$ROOT/m.jsonl" >/dev/null
    if [ $mode = snapshot ]; then
        for _ in $(seq 300); do grep -q "snapshot .* written" "$ROOT/log" && break; sleep 0.1; done
    fi
    sleep 1.2 # everysec: the last second on disk
    kill -9 $PID; wait $PID 2>/dev/null || true
    for run in 1 2 3; do
        start "$ROOT/d" everysec --compact-mb $cm
        line=$(grep -o "scene restored in [0-9]* ms.*entities" "$ROOT/log" | head -1)
        echo "  from $mode, run $run: $line"
        kill -9 $PID; wait $PID 2>/dev/null || true
    done
    du -sh "$ROOT/d" | sed 's/^/  on disk: /'
done

echo "== edit throughput by policy (vantage bench --test edit --clients 8 --pipeline 8 --batch 10)"
for rep in 1 2 3; do
    for pol in none off everysec always; do
        rm -rf "$ROOT/e"
        if [ $pol = none ]; then start "" ""; else start "$ROOT/e" $pol; fi
        out=$("$B/vantage" -p $PORT bench --test edit --clients 8 --pipeline 8 --batch 10 --requests 40000 --json)
        echo "  rep $rep $pol: $out"
        kill $PID; wait $PID 2>/dev/null || true
    done
done
