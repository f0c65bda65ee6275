#!/usr/bin/env python3
"""The cluster's numbers for BENCHMARKS.md (make bench-cluster): a 3-node
NATS JetStream cluster on loopback, streams replicated 3 ways.

  VANTAGE_BIN_DIR=build/release python3 tests/cluster/bench.py [--records N] [--quick]

1. replica lag (the writer's ACK of an edit -> the replica's scene EVENT
   carrying its epoch) at 1k and 10k edit messages/s, and edit throughput,
   with --durability replicated and off;
2. catch-up: a replica started N records behind (default 1,000,000);
3. bootstrap: a replica started on a 1,000,000-entity scene (1000 messages
   of 1000 entities);
4. failover: the writer killed (-9) five times, the time until a replica
   writes;
5. frames: 1 writer + 6 replicas each serving its own viewers, against one
   daemon serving them all, on this machine's 2 cores.
"""
import json
import os
import re
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run  # noqa: E402  (the tests' NATS and daemon helpers)
from run import Daemon, log, wait_for  # noqa: E402

BENCH = os.path.join(run.BIN, "cluster_bench")
QUICK = "--quick" in sys.argv
RECORDS = 1000000
if "--records" in sys.argv:
    RECORDS = int(sys.argv[sys.argv.index("--records") + 1])
if QUICK:
    RECORDS = min(RECORDS, 50000)
rows = []
ONLY = sys.argv[sys.argv.index("--only") + 1].split(",") if "--only" in sys.argv else None


def want(part):
    return ONLY is None or part in ONLY


def bench(*args, timeout=600):
    r = subprocess.run([BENCH, *map(str, args)], capture_output=True, text=True, timeout=timeout)
    if r.returncode:
        log("cluster_bench failed: " + r.stderr.strip()[-300:])
    try:
        return json.loads(r.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        return {}


def cluster(urls, scene, replicas, extra=(), writer_extra=()):
    w = Daemon(f"{scene}-w", urls, scene, False, list(extra) + list(writer_extra))
    w.start()
    if not wait_for(lambda: w.role() == "writer", 30):
        raise RuntimeError(f"{scene}: no writer: {w.tail()}")
    rs = []
    for i in range(replicas):
        r = Daemon(f"{scene}-r{i}", urls, scene, True, list(extra))
        r.start()
        rs.append(r)
    if not wait_for(lambda: all(r.role() == "replica" for r in rs), 60):
        raise RuntimeError(f"{scene}: replicas did not join")
    return w, rs


def stop(*ds):
    for d in ds:
        if d.alive():
            d.p.terminate()
            try:
                d.p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                d.p.kill()


def applied_ms(d, timeout):
    """The replica's own report at start: records applied in all (snapshot
    and stream) and, when it loaded a snapshot, the snapshot's records and
    load time."""
    total = re.compile(r"replica, (\d+) records applied in (\d+) ms")
    snap = re.compile(r"snapshot as of stream message \d+ \((\d+) records, ([\d.]+) MB\) loaded in (\d+) ms")

    def found():
        m = total.findall(open(d.logf).read())
        return m[-1] if m else None
    m = wait_for(found, timeout, 0.2)
    s = snap.findall(open(d.logf).read())
    return dict(records=int(m[0]) if m else None, ms=int(m[1]) if m else None,
                snapshot_records=int(s[-1][0]) if s else 0, snapshot_mb=float(s[-1][1]) if s else 0,
                snapshot_ms=int(s[-1][2]) if s else 0)


def main():
    nats, urls = run.start_nats()
    secs = 2 if QUICK else 5
    try:
        # 1. lag and throughput
        for dur in ("replicated", "off") if want("edits") else ():
            w, (r,) = cluster(urls, f"lag{dur}", 1, writer_extra=["--durability", dur])
            for rate in (1000, 10000, 0):
                b = bench("--writer", w.ep, "--replica", r.ep, "--rate", rate, "--seconds", secs, "--window",
                          512 if rate else 256, "--base", 10000000 * (1 + rate // 1000))
                log(f"{dur} rate {rate or 'max'}: {b}")
                rows.append(dict(kind="edits", durability=dur, rate=rate, **b))
            stop(w, r)
        # 2. catch-up N records behind: from the stream alone (no snapshot), and with snapshots (64 MB)
        for compact in (1 << 20, 64) if want("catchup") else ():
            name = f"catchup{compact}"
            w, _ = cluster(urls, name, 0, writer_extra=["--compact-mb", str(compact)])
            t0 = time.monotonic()
            b = bench("--writer", w.ep, "--rate", 0, "--seconds", 3600, "--window", 1024, "--base", 100000000,
                      "--max", RECORDS, timeout=3600)
            made_s = time.monotonic() - t0
            log(f"made {b.get('messages')} records in {made_s:.1f} s: {b}")
            time.sleep(3)  # a snapshot under way is published
            r = Daemon(f"{name}-r", urls, name, True)
            r.start()
            a = applied_ms(r, 1200)
            log(f"catch-up (--compact-mb {compact}): {a}")
            rows.append(dict(kind="catchup", compact_mb=compact, publish_s=made_s, publish=b, **a))
            stop(w, r)
        # 3. bootstrap a 1M-entity scene
        if want("bootstrap"):
            w, _ = cluster(urls, "boot", 0, writer_extra=["--compact-mb", str(1 << 20)])
            b = bench("--writer", w.ep, "--rate", 0, "--seconds", 1000, "--window", 8, "--batch", 1000, "--base",
                      200000000, "--max", 1000 if not QUICK else 50, timeout=3600)
            r = Daemon("boot-r", urls, "boot", True)
            r.start()
            a = applied_ms(r, 1200)
            ents = (r.stats() or {}).get("entities")
            log(f"bootstrap: {ents} entities: {a}")
            rows.append(dict(kind="bootstrap", entities=ents, **a))
            stop(w, r)
        # 4. failover
        if want("failover"):
            w, rs = cluster(urls, "failover", 2)
            ds = [w] + rs
            times = []
            for k in range(3 if QUICK else 5):
                cur = next(d for d in ds if d.role() == "writer")
                time.sleep(2)
                cur.kill9()
                t0 = time.monotonic()
                nw = wait_for(lambda: next((d for d in ds if d is not cur and d.role() == "writer"), None), 20, 0.05)
                times.append(time.monotonic() - t0 if nw else None)
                cur.start()
                wait_for(lambda: cur.role() == "replica", 30)
                time.sleep(6.5)  # a restarted follower waits 2 leases before it may be promoted
            log(f"failover: {times}")
            rows.append(dict(kind="failover", seconds=times))
            stop(*ds)
        # 5. frames: 7 daemons against 1
        if want("frames"):
            nviewers = 14
            w, rs = cluster(urls, "frames", 6, extra=["--threads", "1"], writer_extra=["--scene", "demo"])
            eps = ",".join(d.ep for d in [w] + rs)
            b7 = bench("--frames", eps, "--viewers", nviewers, "--writer", w.ep, "--seconds", 4 if QUICK else 10,
                       "--size", "640x360")
            stop(w, *rs)
            one = Daemon("frames-one", urls, "framesone", False, ["--threads", "2", "--scene", "demo"])
            one.start()
            wait_for(lambda: one.role() == "writer", 30)
            b1 = bench("--frames", one.ep, "--viewers", nviewers, "--writer", one.ep, "--seconds", 4 if QUICK else 10,
                       "--size", "640x360")
            stop(one)
            log(f"frames: 7 daemons {b7}; 1 daemon {b1}")
            rows.append(dict(kind="frames", seven=b7, one=b1))
    finally:
        for p in run.procs:
            if p.poll() is None:
                p.kill()
    print(json.dumps(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
