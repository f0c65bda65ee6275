#!/usr/bin/env python3
"""make_captures.py — synthetic pad captures in hid-recorder's text format
for the commander's tests and demos (tests/test_commander.c, README).

The reports have the real byte layout of a DualShock 4 v2 over USB
(report 0x01, 64 bytes: docs/INPUT.md, from SDL's SDL_hidapi_ps4.c) at the
pad's 250 reports a second, with its counter and 16/3 us timestamp
running; what a person does with the pad is a script of (seconds, what is
held). A real capture (`vantage pad dump --record FILE`, or hid-recorder)
replays the same way.

    python3 make_captures.py OUT_DIR            # the walk (committed)
    python3 make_captures.py OUT_DIR latency    # the latency circle (make bench-commander)
"""
import math, os, random, sys

RATE = 250.0  # reports per second

def ds4_report(n, t, lx=0.0, ly=0.0, rx=0.0, ry=0.0, l2=0.0, r2=0.0, buttons=()):
    """One USB report; sticks -1..1 with +y up (the pad sends 0 = up)."""
    def axis(v, flip=False):
        v = -v if flip else v
        return max(0, min(255, int(round(128 + v * 127.5))))
    r = bytearray(64)
    r[0] = 0x01
    r[1], r[2], r[3], r[4] = axis(lx), axis(ly, True), axis(rx), axis(ry, True)
    hat = 8  # none
    face = {"square": 0x10, "cross": 0x20, "circle": 0x40, "triangle": 0x80}
    r[5] = hat | sum(face[b] for b in buttons if b in face)
    sh = {"l1": 0x01, "r1": 0x02, "l2": 0x04, "r2": 0x08, "share": 0x10, "options": 0x20, "l3": 0x40, "r3": 0x80}
    r[6] = sum(sh[b] for b in buttons if b in sh) | (0x04 if l2 > 0.05 else 0) | (0x08 if r2 > 0.05 else 0)
    r[7] = (n % 64) << 2
    r[8], r[9] = int(round(l2 * 255)), int(round(r2 * 255))
    ts = int(t * 1e6 / (16.0 / 3)) & 0xFFFF
    r[10], r[11] = ts & 0xFF, ts >> 8
    r[12] = 0x12  # temperature, as real pads send
    # gyro 0, accel: 1 g down the pad's y axis while it lies flat (8192 = 1 g)
    r[21], r[22] = 0x00, 0x20
    r[30] = 0x1B  # battery 11/11 on the cable (bit 4)
    r[35] = 0x80  # touch 0: not touching
    r[39] = 0x80  # touch 1: not touching
    return r

def write(path, script, seconds, name="Sony Interactive Entertainment Wireless Controller", phase=0.0, jitter=0.0,
          moving=None):
    with open(path, "w") as f:
        f.write("# %s: synthetic DualShock 4 v2 capture (tests/data/pads/make_captures.py)\n" % os.path.basename(path))
        f.write("D: 0\n")
        f.write("N: %s\n" % name)
        f.write("P: usb-0000:00:14.0-2/input3\n")
        f.write("I: 3 054c 09cc\n")
        rng = random.Random(2011)
        n = 0
        t = phase
        while t < seconds:
            state = {}
            for (t0, t1, s) in script:
                if t0 <= t < t1:
                    state.update(s)
            if moving:
                state.update(moving(t))
            r = ds4_report(n, t, **state)
            f.write("E: %.6f %d %s\n" % (t, len(r), " ".join("%02x" % b for b in r)))
            n += 1
            t = phase + n / RATE + rng.uniform(-jitter, jitter)

# The commander walk over the demo city (its blocks span +-456 m): pan
# right 0.5 s, forward 0.5 s (192 m each at the start zoom), zoom in 1 s,
# rotate 1 s, select, ping, zoom back out 0.5 s. Times in seconds.
COMMANDER_WALK = [
    (0.50, 1.00, {"lx": 1.0}),
    (1.50, 2.00, {"ly": 1.0}),
    (2.30, 3.30, {"r2": 1.0}),
    (3.50, 4.50, {"rx": 1.0}),
    (4.70, 4.80, {"buttons": ("cross",)}),
    (5.00, 5.10, {"buttons": ("square",)}),
    (5.30, 5.80, {"l2": 1.0}),
]

# The latency capture: the left stick circles at 0.8 of its throw, one
# turn in 4 s, so every report changes the state (each is an input whose
# effect on the picture can be timed); reports at the pad's 4 ms with
# +-0.3 ms of jitter, starting 1.37 ms in, so their phase against the
# commander's tick wanders as a real pad's does.
def circle(t):
    a = 2 * math.pi * t / 4.0
    return {"lx": 0.8 * math.cos(a), "ly": 0.8 * math.sin(a)}

if __name__ == "__main__":
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    if sys.argv[2:] == ["latency"]:
        write(os.path.join(out, "ds4_latency_circle.hidrec"), [], 20.0, phase=0.00137, jitter=0.0003, moving=circle)
    else:
        write(os.path.join(out, "ds4_commander_walk.hidrec"), COMMANDER_WALK, 6.5)
