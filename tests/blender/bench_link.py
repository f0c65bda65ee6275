"""bench_link.py — the live-link's latency and its cost under a drag, in
headless Blender against a real vantaged (make bench-blender; not in make
test: timings never fail tests).

1. Edit latency: N single-object edits (a move of a random one of 500
   objects), one every 10 ms, while the add-on's flush runs as Blender's
   timer would (every 1/60 s). Measured per edit from the depsgraph
   handler's call (the time the add-on first saw it) to the arrival of the
   ACK carrying the daemon epoch that holds it (ACK's epoch: every query
   received after it sees the edit). p50 / p99 / max.
2. A drag of 1,000 objects: all of them moved every frame at 60 Hz for 3 s.
   The main thread's cost per frame (depsgraph handler + flush: what would
   stall Blender's UI), the pending transforms (bounded by the objects:
   one per object) and the latency, handler to ACK, of each frame's moves.

Run: blender -b --factory-startup --python tests/blender/bench_link.py -- [--edits N]
"""
import os
import random
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
import harness as H  # noqa: E402

import bpy  # noqa: E402

import vantage_link as vl  # noqa: E402


def pct(v, p):
    v = sorted(v)
    return v[min(len(v) - 1, int(p / 100.0 * len(v)))] if v else float("nan")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    edits = int(argv[argv.index("--edits") + 1]) if "--edits" in argv else 1000
    rng = random.Random(1)
    tmp = H.tmpdir()
    d = H.Daemon(tmp)
    d.start()
    vl.register()
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    bpy.ops.mesh.primitive_cube_add()
    me = bpy.context.active_object.data
    bpy.data.objects.remove(bpy.context.active_object)
    objs = []
    for n in range(1000):
        o = bpy.data.objects.new("B%04d" % n, me)
        bpy.context.scene.collection.objects.link(o)
        o.location = [rng.uniform(-100, 100) for _ in range(3)]
        objs.append(o)
    m = vl.connect(unix=d.sock, token=H.EDITOR_TOKEN)
    assert m.wait_synced(30), m.status
    lat = m.link.latencies

    # 1. single edits every 10 ms, the flush at 60 Hz
    lat.clear()
    tick_next = time.monotonic()
    edit_next = time.monotonic()
    done = 0
    while done < edits or not m.synced():
        now = time.monotonic()
        if done < edits and now >= edit_next:
            o = objs[rng.randrange(500)]
            o.location.x += rng.uniform(-1, 1)
            bpy.context.view_layer.update()  # the depsgraph handler runs here
            done += 1
            edit_next += 0.010
        if now >= tick_next:
            m.tick()
            tick_next += 1.0 / 60.0
        time.sleep(0.0005)
    e = [x * 1e3 for x in lat]
    print("edit latency, handler -> ACK of its epoch, %d edits (one every 10 ms, flush at 60 Hz): "
          "p50 %.2f ms, p99 %.2f ms, max %.2f ms (%d samples)" % (edits, pct(e, 50), pct(e, 99), max(e), len(e)))

    # 2. a drag of 1,000 objects at 60 Hz for 3 s
    lat.clear()
    frame_ms, pend = [], 0
    t_end = time.monotonic() + 3.0
    nxt = time.monotonic()
    frames = 0
    while time.monotonic() < t_end:
        nxt += 1.0 / 60.0
        t0 = time.monotonic()
        for o in objs:
            o.location.z += 0.01
        t1 = time.monotonic()
        bpy.context.view_layer.update()
        m.tick()
        t2 = time.monotonic()
        frame_ms.append((t2 - t1) * 1e3)  # the add-on's share: handler + flush (not Blender's own move)
        pend = max(pend, m.link.pending())
        frames += 1
        time.sleep(max(0.0, nxt - time.monotonic()))
    m.wait_synced(30)
    e = [x * 1e3 for x in lat]
    print("drag of 1,000 objects at 60 Hz, %d frames: depsgraph update + add-on flush per frame p50 %.2f ms, "
          "p99 %.2f ms; pending transforms at most %d (one per object); handler -> ACK p50 %.2f ms, p99 %.2f ms"
          % (frames, pct(frame_ms, 50), pct(frame_ms, 99), pend, pct(e, 50), pct(e, 99)))
    H.check_converged(bpy, d, "after the drag")
    print("sent: %s" % dict(m.link.counters))
    vl.disconnect()
    H.finish(d, tmp)


H.run(main)
