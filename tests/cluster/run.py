#!/usr/bin/env python3
"""The cluster tests (issue 23): vantaged --cluster against a real 3-node
NATS JetStream cluster on loopback, the stream replicated 3 ways.

  VANTAGE_BIN_DIR=build/release python3 tests/cluster/run.py

Independent parts: Debian's nats-server, the C CLI (`vantage stats --json`,
`vantage export -`) and cluster_editor (libvantage) as the clients. Phases:

1. convergence under faults: a writer and 2 replicas, 5 editors adding
   entities at a steady rate for 20 s while a replica is killed (-9) and
   restarted, a NATS server is killed and restarted, the writer is killed
   (-9: a replica must take over within 5 s) and restarted (it must come
   back as a replica). Every daemon must end at the same epoch with the same
   scene, holding every edit an editor saw acknowledged.
2. split brain: a writer whose only NATS server stops cannot acknowledge
   an edit; a replica takes over; the old writer steps down (its scene made
   anew from the stream once its server is back: a replica of the new
   writer), never writes over the new writer's edits, and the edit it could
   not acknowledge is nowhere.
3. snapshots: a writer publishing a snapshot every MB of records trims the
   stream behind it; a new replica starts from the newest snapshot, and a
   replica stalled (SIGSTOP) while the stream was trimmed past it starts
   again from one in place; both end with the writer's scene.
4. a balancer: Debian's HAProxy with the shipped configuration
   (docs/scale-out/haproxy.cfg) spreads clients over the daemons and, by its
   protocol health check (HELLO + PING), routes around a dead one.
5. bad stream data: a foreign message put on the stream stops a replica,
   with the message's sequence in its log, instead of diverging.
6. TLS: a writer and a replica with --cluster-ca against a TLS-only NATS
   server (a CA and a certificate made here by openssl); without the CA a
   daemon is refused at the handshake.
"""
import hashlib
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

BIN = os.environ.get("VANTAGE_BIN_DIR", "build/release")
VANTAGED, VANTAGE, EDITOR, BENCH = (os.path.join(BIN, n) for n in ("vantaged", "vantage", "cluster_editor",
                                                                   "cluster_bench"))
NATS = shutil.which("nats-server")
LEASE_MS = 3000           # the default: the failover bound below is for it
RUN_S = float(os.environ.get("VANTAGE_CLUSTER_RUN_S", "20"))

tmp = tempfile.mkdtemp(prefix="vantage-cluster.")
procs = []                # every process started, for the cleanup
failures = []


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def check(cond, what):
    if cond:
        log(f"ok   {what}")
    else:
        log(f"FAIL {what}")
        failures.append(what)
    return cond


def wait_for(fn, timeout, step=0.1):
    end = time.monotonic() + timeout
    while True:
        v = fn()
        if v or time.monotonic() > end:
            return v
        time.sleep(step)


class Nats:
    def __init__(self, i, ports, cports):
        self.i, self.port = i, ports[i]
        self.conf = os.path.join(tmp, f"nats{i}.conf")
        routes = ", ".join(f"nats-route://127.0.0.1:{p}" for p in cports)
        # no_advertise: a client knows the servers it was given, so a daemon
        # given one server is cut off when that one stops (phase 2)
        with open(self.conf, "w") as f:
            f.write(f"server_name: n{i}\nlisten: 127.0.0.1:{self.port}\n"
                    f"jetstream {{ store_dir: {tmp}/js{i}, max_memory_store: 64MB, max_file_store: 2GB }}\n"
                    f"cluster {{ name: vantage, listen: 127.0.0.1:{cports[i]}, routes: [{routes}], no_advertise: true }}\n")
        self.p = None
        self.url = f"nats://127.0.0.1:{self.port}"

    def start(self):
        self.p = subprocess.Popen([NATS, "-c", self.conf], stdout=open(f"{tmp}/nats{self.i}.log", "a"),
                                  stderr=subprocess.STDOUT)
        procs.append(self.p)

        def listening():
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.5).close()
                return True
            except OSError:
                return False
        wait_for(listening, 10, 0.05)

    def kill(self):
        self.p.kill()
        self.p.wait()


class Daemon:
    def __init__(self, name, urls, scene, follow, extra=()):
        self.name, self.urls, self.scene, self.follow, self.extra = name, urls, scene, follow, list(extra)
        self.port = free_port()
        self.ep = f"127.0.0.1:{self.port}"
        self.logf = f"{tmp}/{name}.log"
        self.p = None

    def start(self):
        args = [VANTAGED, "--cluster", ",".join(self.urls), "--follow" if self.follow else "--scene-name",
                self.scene, "--scene", "empty", "--stream-replicas", "3", "--bind", "127.0.0.1", "--port",
                str(self.port), "--unix", "", "--threads", "1"] + self.extra
        self.p = subprocess.Popen(args, stdout=open(self.logf, "a"), stderr=subprocess.STDOUT)
        procs.append(self.p)

    def kill9(self):
        self.p.send_signal(signal.SIGKILL)
        self.p.wait()

    def alive(self):
        return self.p and self.p.poll() is None

    def stats(self):
        try:
            r = subprocess.run([VANTAGE, "-h", self.ep, "--timeout", "2000", "stats", "--json"], capture_output=True,
                               text=True, timeout=5)
            return json.loads(r.stdout) if r.returncode == 0 else None
        except (subprocess.TimeoutExpired, json.JSONDecodeError):
            return None

    def role(self):
        s = self.stats()
        return s.get("cluster", {}).get("role") if s else None

    def export(self):
        r = subprocess.run([VANTAGE, "-h", self.ep, "--timeout", "10000", "export", "-"], capture_output=True,
                           timeout=60)
        return r.stdout if r.returncode == 0 else None

    def tail(self, n=15):
        try:
            return "".join(open(self.logf).readlines()[-n:])
        except OSError:
            return ""


def start_nats():
    """Three JetStream servers clustered on loopback: (servers, their URLs)."""
    ports = [free_port() for _ in range(3)]
    cports = [free_port() for _ in range(3)]
    nats = [Nats(i, ports, cports) for i in range(3)]
    for n in nats:
        n.start()
    time.sleep(1.5)  # the cluster's routes and a JetStream meta leader
    return nats, [n.url for n in nats]


def acked_ids(paths):
    ids = set()
    for p in paths:
        for line in open(p):
            f = line.split()
            if f and f[0] in ("A", "D"):
                ids.add(int(f[1]))
    return ids, sum(1 for p in paths for line in open(p) if line.startswith("A "))


def scene_ids(export):
    return {json.loads(l)["id"] for l in export.decode().splitlines() if l.startswith("{")}


def converge(daemons, timeout=30):
    """Every daemon at the same epoch, with the same scene: (ok, epoch, digest)."""
    def same_epoch():
        e = [d.stats() for d in daemons]
        if any(s is None for s in e):
            return None
        return e[0]["epoch"] if len({s["epoch"] for s in e}) == 1 else None
    epoch = wait_for(same_epoch, timeout, 0.3)
    if epoch is None:
        return False, [d.stats() and d.stats()["epoch"] for d in daemons], None
    digests = [hashlib.sha256(d.export() or b"none").hexdigest() for d in daemons]
    return len(set(digests)) == 1, epoch, digests[0]


def phase_convergence(nats, urls):
    log("phase 1: convergence, 5 editors for %.0f s, with faults" % RUN_S)
    w = Daemon("writer", urls, "conv", False)
    r1 = Daemon("replica1", urls, "conv", True)
    r2 = Daemon("replica2", urls, "conv", True)
    w.start()
    check(wait_for(lambda: w.role() == "writer", 20), "the first daemon becomes the writer")
    r1.start()
    r2.start()
    check(wait_for(lambda: r1.role() == "replica" and r2.role() == "replica", 20), "two replicas join")
    eps = ",".join(d.ep for d in (r1, r2, w))  # editors start at a replica: NOT_WRITER sends them on
    editors = []
    for k in range(5):
        lf = f"{tmp}/editor{k}.log"
        p = subprocess.Popen([EDITOR, "--endpoints", eps, "--base", str((k + 1) * 1000000), "--rate", "20",
                              "--seconds", str(RUN_S), "--log", lf], stdout=subprocess.PIPE, text=True)
        procs.append(p)
        editors.append((p, lf))
    t0 = time.monotonic()

    def at(t):
        d = t0 + t * RUN_S / 20 - time.monotonic()
        if d > 0:
            time.sleep(d)
    at(3)
    log("kill -9 replica2")
    r2.kill9()
    at(5)
    r2.start()
    at(7)
    log("kill NATS server n2")
    nats[2].kill()
    at(9)
    nats[2].start()
    at(11)
    log("kill -9 the writer")
    w.kill9()
    tk = time.monotonic()
    # an edit sent by the CLI in the middle of the failover waits it out
    during = subprocess.Popen([VANTAGE, "-h", f"{r1.ep},{r2.ep}", "add", "990001", "9,9,9", "1"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    new = wait_for(lambda: next((d for d in (r1, r2) if d.role() == "writer"), None), 15, 0.05)
    took = time.monotonic() - tk
    check(new is not None and took < 5.0, f"a replica took over {took:.2f} s after the writer died (under 5 s)")
    out, _ = during.communicate(timeout=30)
    check(during.returncode == 0, "an edit the CLI sent during the failover waited and was applied: " +
          out.strip()[-120:])
    at(15)
    log("the old writer restarted")
    w.start()
    check(wait_for(lambda: w.role() == "replica", 20), "the old writer came back as a replica")
    for p, _ in editors:
        out, _ = p.communicate(timeout=RUN_S + 60)
        log("  " + out.strip())
    ok, epoch, digest = converge([w, r1, r2])
    check(ok, f"every daemon at epoch {epoch} with the same scene (sha256 {digest and digest[:16]})")
    ids, nacked = acked_ids([lf for _, lf in editors])
    for d in (w, r1, r2):
        ex = d.export()
        have = scene_ids(ex) if ex else set()
        missing = ids - have
        check(ex is not None and not missing,
              f"{d.name}: all {nacked} acknowledged edits are in its scene ({len(have)} entities, "
              f"{len(missing)} missing)")
    check(nacked > 5 * 20 * RUN_S * 0.5, f"the editors got {nacked} edits acknowledged (at least half the rate)")
    return (w, r1, r2)


def phase_split_brain(nats, urls):
    log("phase 2: split brain")
    s = Daemon("isolated", [nats[0].url], "split", False)
    r = Daemon("splitreplica", [nats[1].url, nats[2].url], "split", True)
    s.start()
    check(wait_for(lambda: s.role() == "writer", 20), "the writer on n0 only is the writer")
    r.start()
    check(wait_for(lambda: r.role() == "replica", 20), "its replica on n1, n2 joins")
    ok = subprocess.run([VANTAGE, "-h", s.ep, "add", "7001", "1,1,1", "1"], capture_output=True).returncode == 0
    check(ok, "an edit before the split is acknowledged")
    log("kill NATS server n0: the writer is cut off")
    nats[0].kill()
    r_cut = subprocess.run([VANTAGE, "-h", s.ep, "--timeout", "2500", "add", "7002", "2,2,2", "1"],
                           capture_output=True, text=True)
    check(r_cut.returncode != 0, "the cut-off writer does not acknowledge an edit (%s)" %
          (r_cut.stderr.strip().splitlines() or ["no answer"])[-1][:120])
    check(wait_for(lambda: r.role() == "writer", 15), "the replica took over")
    ok = subprocess.run([VANTAGE, "-h", r.ep, "add", "7003", "3,3,3", "1"], capture_output=True).returncode == 0
    check(ok, "an edit through the new writer is acknowledged")
    stepped = wait_for(lambda: "stepping down" in open(s.logf).read(), 15)
    check(stepped, "the cut-off writer stepped down: " +
          next((l.split("WARN  ")[-1].strip()[:160] for l in open(s.logf) if "stepping down" in l), "it did not"))
    nats[0].start()
    check(s.alive() and wait_for(lambda: s.role() == "replica", 30),
          "once its NATS server is back, the old writer is a replica (not restarted)")
    ok2, epoch, _ = converge([s, r])
    check(ok2, f"both at epoch {epoch} with the same scene")
    for d in (r, s):
        have = scene_ids(d.export() or b"")
        check(7001 in have and 7003 in have and 7002 not in have,
              f"{d.name}: the edits before and after the split, not the unacknowledged one")
    return (s, r)


def noise_png(path, w, h):
    """A PNG of random RGB (it does not compress: about 3 bytes a pixel)."""
    import random
    import struct
    import zlib
    rnd = random.Random(7)
    raw = b"".join(b"\0" + rnd.randbytes(3 * w) for _ in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 1)) + chunk(b"IEND", b""))


def metric(d, name):
    r = subprocess.run([VANTAGE, "-h", d.ep, "stats", "--metrics"], capture_output=True, text=True, timeout=10)
    m = re.search(r"^" + name + r" (\d+)", r.stdout, re.M)
    return int(m.group(1)) if m else None


def phase_snapshots(urls):
    log("phase 3: snapshots on JetStream, the stream trimmed, a replica bootstrapped from one")
    w = Daemon("snapwriter", urls, "snap", False, ["--compact-mb", "1"])
    w.start()
    check(wait_for(lambda: w.role() == "writer", 20), "the writer of scene snap")
    lag = Daemon("snaplagger", urls, "snap", True)
    lag.start()
    check(wait_for(lambda: lag.role() == "replica", 20), "a replica follows from the start")
    png = os.path.join(tmp, "noise.png")
    noise_png(png, 1024, 1024)
    up = subprocess.run([VANTAGE, "-h", w.ep, "texture", "put", "77", png], capture_output=True, text=True)
    check(up.returncode == 0, f"a {os.path.getsize(png) / 1e6:.1f} MB texture uploaded (a record in several stream "
          "messages: NATS takes 1 MB a message)")
    tb = metric(w, "vantage_scene_texture_bytes")
    check(tb and wait_for(lambda: metric(lag, "vantage_scene_texture_bytes") == tb, 10),
          f"the replica holds the same texture bytes ({tb})")
    lag.p.send_signal(signal.SIGSTOP)  # ... and stalls while the stream is trimmed past it
    r = subprocess.run([BENCH, "--writer", w.ep, "--rate", "0", "--batch", "100", "--max", "300", "--window", "8",
                        "--seconds", "60"], capture_output=True, text=True, timeout=120)
    check(r.returncode == 0, "300 edits of 100 entities each acknowledged (about 4 MB of records)")
    n = wait_for(lambda: len(re.findall(r"snapshot as of stream message \d+ published", open(w.logf).read())) >= 2,
                 20)
    check(n, "the writer published snapshots: " + "; ".join(
        l.split("INFO  ")[-1] for l in open(w.logf) if "published" in l)[:300])
    check("trimmed below message" in open(w.logf).read(), "and trimmed the stream behind them")
    rep = Daemon("snapreplica", urls, "snap", True)
    rep.start()
    check(wait_for(lambda: rep.role() == "replica", 20), "a new replica joined")
    check("loaded in" in open(rep.logf).read(), "from a snapshot: " +
          next((l.split("INFO  ")[-1].strip() for l in open(rep.logf) if "loaded in" in l), "none"))
    ok, epoch, digest = converge([w, rep])
    check(ok, f"writer and replica at epoch {epoch} with the same scene")
    time.sleep(1)
    lag.p.send_signal(signal.SIGCONT)
    ok, epoch, digest = converge([w, rep, lag])
    again = next((l.split("WARN  ")[-1].strip() for l in open(lag.logf) if "started again" in l), None)
    check(ok, f"the stalled replica caught up, at epoch {epoch} with the same scene" +
          (f" ({again})" if again else " (from the stream)"))
    for d in (w, rep, lag):
        d.p.terminate()


def phase_tls():
    log("phase 6: TLS to NATS (--cluster-ca)")
    ossl = shutil.which("openssl")
    if not check(ossl, "openssl is installed"):
        return
    d = os.path.join(tmp, "tls")
    os.makedirs(d)

    def sh(*a):
        subprocess.run([ossl, *a], cwd=d, check=True, capture_output=True)
    sh("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out", "ca.pem", "-days", "2",
       "-subj", "/CN=vantage test CA")
    sh("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "srv.key", "-out", "srv.csr", "-subj", "/CN=localhost")
    with open(os.path.join(d, "ext"), "w") as f:
        f.write("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    sh("x509", "-req", "-in", "srv.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial", "-out", "srv.pem",
       "-days", "2", "-extfile", "ext")
    port = free_port()
    p = subprocess.Popen([NATS, "--jetstream", "--store_dir", f"{d}/js", "-a", "127.0.0.1", "-p", str(port), "--tls",
                          "--tlscert", f"{d}/srv.pem", "--tlskey", f"{d}/srv.key"],
                         stdout=open(f"{tmp}/nats-tls.log", "a"), stderr=subprocess.STDOUT)
    procs.append(p)
    time.sleep(1)
    url = [f"tls://127.0.0.1:{port}"]
    ca = ["--cluster-ca", f"{d}/ca.pem", "--stream-replicas", "1"]  # one server
    w = Daemon("tlswriter", url, "tls", False, ca)
    w.start()
    check(wait_for(lambda: w.role() == "writer", 20), "a writer over TLS")
    r = Daemon("tlsreplica", url, "tls", True, ca)
    r.start()
    check(wait_for(lambda: r.role() == "replica", 20), "and a replica")
    ok = subprocess.run([VANTAGE, "-h", f"{r.ep},{w.ep}", "add", "8001", "1,1,1", "1"], capture_output=True, text=True)
    check(ok.returncode == 0, "an edit through the replica's redirect, over TLS " + ok.stderr.strip()[-150:])
    ok2, epoch, _ = converge([w, r])
    check(ok2 and epoch == 1, f"both at epoch {epoch} with the same scene")
    bad = Daemon("tlsnoca", url, "tls", True, ["--stream-replicas", "1"])
    bad.start()
    code = bad.p.wait(timeout=30)
    check(code != 0 and "SSL handshake" in open(bad.logf).read(),
          f"without --cluster-ca the server's certificate is refused (exit {code})")
    for x in (w, r):
        x.p.terminate()
    p.terminate()


def phase_balancer(daemons):
    log("phase 4: HAProxy in front of the daemons (docs/scale-out/haproxy.cfg)")
    hap = shutil.which("haproxy") or shutil.which("haproxy", path="/usr/sbin:/usr/local/sbin")
    if not check(hap, "haproxy is installed"):
        return
    port = free_port()
    cfg = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs", "scale-out", "haproxy.cfg")
    env = dict(os.environ, VANTAGE_LISTEN=f"127.0.0.1:{port}",
               **{f"VANTAGE_D{i + 1}": d.ep for i, d in enumerate(daemons)})
    p = subprocess.Popen([hap, "-f", cfg, "-db"], env=env, stdout=open(f"{tmp}/haproxy.log", "a"),
                         stderr=subprocess.STDOUT)
    procs.append(p)
    time.sleep(1.5)  # two good checks (rise 2, every 500 ms)

    def stats_count(d):
        s = d.stats()
        return s.get("requests", {}).get("stats", {}).get("count", 0) if s else None

    def through(n):
        ok = 0
        for _ in range(n):
            r = subprocess.run([VANTAGE, "-h", f"127.0.0.1:{port}", "--timeout", "3000", "stats"], capture_output=True)
            ok += r.returncode == 0
        return ok
    before = [stats_count(d) for d in daemons]
    n = through(12)
    after = [stats_count(d) for d in daemons]
    served = sum(1 for b, a in zip(before, after) if b is not None and a is not None and a - b >= 2)  # ours + its own
    check(n == 12 and served >= 2, f"12 clients through HAProxy answered ({n}), spread over {served} daemons")
    victim = next((d for d in daemons if d.role() == "replica"), None)
    if not check(victim, "a replica to take down"):
        return
    victim.kill9()
    time.sleep(1.5)  # two failed checks
    n = through(10)
    check(n == 10, f"with a replica dead, HAProxy's health check routes around it: {n} of 10 answered")
    victim.start()
    check(wait_for(lambda: victim.role() == "replica", 20), "the replica restarted and caught up")
    p.terminate()


def phase_bad_data(nats, daemons):
    log("phase 5: a foreign message on the stream")
    w, r1, r2 = daemons
    live = [d for d in daemons if d.alive() and d.role() == "replica"]
    if not check(live, "a replica to poison"):
        return
    st = live[0].stats()
    seq = int(st["cluster"]["last"]) + 1
    with socket.create_connection(("127.0.0.1", nats[1].port)) as c:
        c.recv(4096)  # INFO
        body = b"not a vantage record"
        c.sendall(b"CONNECT {\"verbose\":false}\r\nPUB vantage.conv.journal %d\r\n%s\r\nPING\r\n" % (len(body), body))
        c.recv(4096)
    stopped = wait_for(lambda: not live[0].alive(), 10)
    tail = live[0].tail(4)
    check(stopped and live[0].p.returncode == 3, f"the replica stopped (exit {live[0].p.poll()})")
    check(f"stream message {seq}" in tail, f"its log names stream message {seq}: {tail.strip().splitlines()[-1:]}")


def main():
    for f in (VANTAGED, VANTAGE, EDITOR, BENCH):
        if not os.access(f, os.X_OK):
            print(f"run.py: {f} is missing: build first (make CONFIG=release all)", file=sys.stderr)
            return 2
    if not NATS:
        print("run.py: nats-server is missing (make deps installs it)", file=sys.stderr)
        return 2
    nats, urls = start_nats()
    t0 = time.monotonic()
    try:
        daemons = phase_convergence(nats, urls)
        phase_split_brain(nats, urls)
        phase_snapshots(urls)
        phase_balancer(daemons)
        phase_bad_data(nats, daemons)
        phase_tls()
    except Exception as e:  # a harness fault is a failure too, with what it was
        import traceback
        traceback.print_exc()
        failures.append(f"exception: {e}")
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
    log(f"cluster tests: {len(failures)} failed, {time.monotonic() - t0:.1f} s")
    if failures:
        for f in sorted(os.listdir(tmp)):
            if f.endswith(".log") and not f.startswith("editor"):
                print(f"---- {f} (last lines)")
                print("".join(open(os.path.join(tmp, f), errors="replace").readlines()[-12:]))
        print(f"(logs kept in {tmp})")
        return 1
    shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
