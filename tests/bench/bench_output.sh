#!/bin/bash
# bench_output.sh OLD_BIN_DIR [REPS] — the output path (issue 25) measured
# in one run: OLD_BIN_DIR's vantaged (main, built in a separate checkout)
# against this tree's build/release/vantaged, interleaved REPS times (7).
# Each run: 2 viewers on RAW 1280x720 frame streams for 4 s (frames/s, and
# the daemon's CPU per frame: its loop thread and the whole process, from
# /proc ticks), then `vantage bench --test ping` and `--test query
# --count-only` (q/s, p99). The medians are printed last. Then, under
# callgrind (deterministic), the daemon's instructions per PING with 1,000
# idle clients connected and with none.
set -e
OLD=$1; REPS=${2:-7}; NEW=build/release; cli=$NEW/vantage
[ -x "$OLD/vantaged" ] || { echo "usage: $0 OLD_BIN_DIR [REPS]" >&2; exit 2; }
dir=$(mktemp -d); trap 'rm -rf $dir' EXIT
cc -O2 -D_GNU_SOURCE -Iprotocol -Iclient/lib -o $dir/clients tests/bench/bench_output_clients.c $NEW/libvantage.a -lm -pthread
ticks() { awk '{print $14+$15}' $1; }
start() { # start BIN_DIR [valgrind...]: the daemon on $dir/d.sock, pid in $pid
    rm -f $dir/d.sock; local b=$1; shift
    "$@" $b/vantaged --bind "" --unix $dir/d.sock --scene empty --threads 2 --max-clients 2000 >/dev/null 2>$dir/log &
    pid=$!
    for i in $(seq 150); do [ -S $dir/d.sock ] && break; sleep 0.2; done; sleep 0.3
}
for r in $(seq $REPS); do
    for which in old new; do
        [ $which = old ] && B=$OLD || B=$NEW
        start $B
        l0=$(ticks /proc/$pid/task/$pid/stat); p0=$(ticks /proc/$pid/stat)
        out=$($dir/clients stream $dir/d.sock 1280 720 2 4)
        l1=$(ticks /proc/$pid/task/$pid/stat); p1=$(ticks /proc/$pid/stat)
        ping=$($cli -s $dir/d.sock bench --test ping --clients 8 --requests 400000 --pipeline 8 --json)
        query=$($cli -s $dir/d.sock bench --test query --count-only --clients 8 --requests 100000 --pipeline 4 --json)
        kill $pid; wait $pid 2>/dev/null || true
        echo "$which rep=$r frames=${out% *} secs=${out#* } loop_ticks=$((l1 - l0)) proc_ticks=$((p1 - p0)) PING $ping QUERY $query" | tee -a $dir/runs
    done
done
python3 - $dir/runs <<'PY'
import json, re, statistics as st, sys, os
tck = os.sysconf('SC_CLK_TCK')
rows = {'old': [], 'new': []}
for l in open(sys.argv[1]):
    m = re.match(r'(\w+) rep=\d+ frames=(\d+) secs=([\d.]+) loop_ticks=(\d+) proc_ticks=(\d+) PING (.*) QUERY (.*)', l)
    p, q = json.loads(m.group(6)), json.loads(m.group(7))
    f = int(m.group(2))
    rows[m.group(1)].append((f / float(m.group(3)), int(m.group(4)) * 1e3 / tck / f, int(m.group(5)) * 1e3 / tck / f,
                             p['per_second'], p['p99_ms'], q['per_second'], q['p99_ms']))
print('medians     frames/s  loop ms/frame  daemon ms/frame  ping q/s  ping p99 ms  query q/s  query p99 ms')
for k, v in rows.items():
    print('%-3s (n=%d) ' % (k, len(v)) + '  '.join('%9.2f' % st.median(c) for c in zip(*v)))
PY
ulimit -n 4096
for which in old new; do
    [ $which = old ] && B=$OLD || B=$NEW
    for idle in 0 1000; do
        for n in 80 20000; do
            start $B valgrind --tool=callgrind --callgrind-out-file=/dev/null
            if [ $idle -gt 0 ]; then
                $dir/clients idle $dir/d.sock $idle 600 >$dir/idle & ip=$!
                for i in $(seq 300); do grep -q ready $dir/idle 2>/dev/null && break; sleep 0.2; done
            fi
            $cli -s $dir/d.sock bench --test ping --clients 8 --requests $n --pipeline 8 >/dev/null
            [ $idle -gt 0 ] && { kill $ip; wait $ip 2>/dev/null || true; }
            kill $pid; wait $pid 2>/dev/null || true
            ir[$n]=$(sed -n 's/.*Collected : \([0-9]*\).*/\1/p' $dir/log)
        done
        echo "callgrind $which, $idle idle clients: $(( (ir[20000] - ir[80]) / 19920 )) daemon instructions per PING"
    done
done
