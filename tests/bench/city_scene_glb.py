#!/usr/bin/env python3
"""city_scene_glb.py - the benchmark city scene as a glTF 2.0 level (.glb).

Converts tests/data/scenes/city_scene.txt (1,000 axis-aligned occluder boxes
given as 12 triangles each, 15,000 test-object AABBs, one camera; the format
is in the file's header and tests/scene_file.c) into a binary glTF that
`vantage import` loads into a running daemon as one sub-level, so the same
scene the offline culling benches use can be benchmarked inside vantaged.

What the .glb holds (README "Authoring levels"; client/import/import_walk.c):
  * one shared mesh, a unit cube centred on the origin (24 vertices with
    per-face normals, 12 triangles counter-clockwise seen from outside, no
    material: the daemon's default material 0, so no global material id is
    replaced); the importer uploads it once as one mesh class;
  * node "obj_<i>" per test object i, in file order: translation = the AABB's
    centre, scale = its size, mesh = the cube. Each becomes an entity; entity
    ids are 2^63 | sublevel << 32 | i, so entity index i is object i;
  * node "OCC_<k>" per occluder box k (k = row*40+col as in the text file):
    the same cube on the box's centre and size. A node named OCC_<name> is an
    occluder only (not drawn); no entity is named "<k>", so each is a free
    occluder (id 2^63 | sublevel << 32 | 2^31 | k);
  * node "camera": the scene's street-level camera as a glTF perspective
    camera (ignored by the importer; for viewers such as Blender). Its eye and
    target are also printed and kept in asset.extras.
World units are the scene's own: metres, y up, right-handed (as glTF).
Centres and sizes are rounded to float32 as glTF readers read them; the
script prints how far the rebuilt box corners land from the text file's.

Usage:
  python3 tests/bench/city_scene_glb.py --out /tmp/city_scene.glb
      [--scene tests/data/scenes/city_scene.txt]
  build/release/vantaged --scene empty --port 7711 --unix "" --log-level warn &
  build/release/vantage -p 7711 import /tmp/city_scene.glb   # sub-level "city_scene"
  build/release/vantage -p 7711 sublevel list                # 15000 entities, 1000 occluders
  build/release/vantage -p 7711 query --eye 1,1.7,220 --at 36,6,1000 --size 1280x720
  build/release/vantage -p 7711 bench --test query --clients 8 --threads 1 --requests 2000 --count-only
  build/release/vantage -p 7711 sublevel unload city_scene   # before importing it again
(`vantage bench --test query` orbits a camera at radius 200 m, 2 m up, around
and looking at (0, 2, 0): the south edge of this city, which spans x -820..820,
z -20..1020, so about half of the orbit looks into the city.)

Python 3 standard library only.
"""
import argparse
import json
import math
import os
import struct
import sys


def die(msg):
    sys.stderr.write("city_scene_glb.py: %s\n" % msg)
    sys.exit(1)


def f32(x):
    """x rounded to the nearest float32, as a Python float."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def read_scene(path):
    """(camera, boxes, objects): camera a dict, boxes and objects lists of
    [minx, miny, minz, maxx, maxy, maxz]; the file checked as
    tests/scene_file.c checks it (counts match, numbers finite)."""
    try:
        f = open(path, "r")
    except OSError as e:
        die("%s: %s" % (path, e.strerror))
    with f:
        lines = []
        for ln, line in enumerate(f, 1):
            s = line.strip()
            if s and not s.startswith("#"):
                lines.append((ln, s))
    pos = 0

    def nums(k, n):
        ln, s = lines[k]
        try:
            v = [float(t) for t in s.split()]
        except ValueError:
            die("%s:%d: not a number in '%s'" % (path, ln, s))
        if len(v) != n or not all(math.isfinite(x) for x in v):
            die("%s:%d: expected %d finite numbers" % (path, ln, n))
        return v

    def section(key):
        nonlocal pos
        if pos >= len(lines):
            die("%s: ends before '%s'" % (path, key))
        ln, s = lines[pos]
        t = s.split()
        if len(t) != 2 or t[0] != key or not t[1].isdigit():
            die("%s:%d: expected '%s N'" % (path, ln, key))
        pos += 1
        n = int(t[1])
        if pos + n > len(lines):
            die("%s: '%s %d' but the file ends first" % (path, key, n))
        rows = [nums(pos + i, 9 if key == "occluder_triangles" else 6) for i in range(n)]
        pos += n
        return rows

    if not lines or lines[0][1].split()[0] != "camera":
        die("%s: expected 'camera' first" % path)
    c = [float(t) for t in lines[0][1].split()[1:]]
    if len(c) != 13 or not all(math.isfinite(x) for x in c):
        die("%s:%d: camera needs 13 numbers" % (path, lines[0][0]))
    camera = {"eye": c[0:3], "target": c[3:6], "up": c[6:9], "fovy_deg": c[9], "near": c[10], "far": c[11],
              "aspect": c[12]}
    pos = 1
    tris = section("occluder_triangles")
    objects = section("objects")
    if pos >= len(lines) or lines[pos][1] != "end":
        die("%s: expected 'end' after the objects" % path)

    if len(tris) % 12:
        die("%s: %d occluder triangles is not 12 a box" % (path, len(tris)))
    boxes = []
    for k in range(len(tris) // 12):
        vs = [t[3 * j:3 * j + 3] for t in tris[12 * k:12 * k + 12] for j in range(3)]
        lo = [min(v[a] for v in vs) for a in range(3)]
        hi = [max(v[a] for v in vs) for a in range(3)]
        # an axis-aligned box: every coordinate is its axis's min or max
        if any(v[a] != lo[a] and v[a] != hi[a] for v in vs for a in range(3)):
            die("%s: occluder box %d (triangles %d..%d) is not an axis-aligned box" % (path, k, 12 * k, 12 * k + 11))
        boxes.append(lo + hi)
    for i, o in enumerate(objects):
        if any(o[3 + a] < o[a] for a in range(3)):
            die("%s: object %d has min > max" % (path, i))
    return camera, boxes, objects


def cube():
    """The unit cube centred on the origin: positions, normals (24 vertices,
    4 a face) and 36 indices, counter-clockwise seen from outside."""
    pos, nrm, idx = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = [0.0, 0.0, 0.0]
            n[axis] = sign
            u, v = (axis + 1) % 3, (axis + 2) % 3  # u x v = +axis
            if sign < 0:
                u, v = v, u
            base = len(pos)
            for du, dv in ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)):
                p = [0.0, 0.0, 0.0]
                p[axis] = 0.5 * sign
                p[u], p[v] = du, dv
                pos.append(p)
                nrm.append(n)
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    # check the winding: (p1-p0) x (p2-p0) points along the face normal
    for t in range(0, len(idx), 3):
        a, b, c = (pos[i] for i in idx[t:t + 3])
        e1 = [b[i] - a[i] for i in range(3)]
        e2 = [c[i] - a[i] for i in range(3)]
        x = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
        assert sum(x[i] * nrm[idx[t]][i] for i in range(3)) > 0
    return pos, nrm, idx


def centre_size(b):
    """The box as float32 centre and size, and the largest distance of the
    rebuilt corners (c -+ s/2) from the given ones."""
    c = [f32(0.5 * (b[a] + b[3 + a])) for a in range(3)]
    s = [f32(b[3 + a] - b[a]) for a in range(3)]
    err = max(max(abs(c[a] - 0.5 * s[a] - b[a]), abs(c[a] + 0.5 * s[a] - b[3 + a])) for a in range(3))
    return c, s, err


def look_at_quat(eye, target, up):
    """The rotation (x, y, z, w) turning a glTF camera (looking down -z, y
    up) to look from eye at target."""
    f = [target[i] - eye[i] for i in range(3)]
    fl = math.sqrt(sum(x * x for x in f))
    f = [x / fl for x in f]
    r = [f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2], f[0] * up[1] - f[1] * up[0]]
    rl = math.sqrt(sum(x * x for x in r))
    r = [x / rl for x in r]
    u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]]
    # columns: right, up, back
    m = [[r[0], u[0], -f[0]], [r[1], u[1], -f[1]], [r[2], u[2], -f[2]]]
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        k = 2 * math.sqrt(tr + 1)
        q = [(m[2][1] - m[1][2]) / k, (m[0][2] - m[2][0]) / k, (m[1][0] - m[0][1]) / k, k / 4]
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        k = 2 * math.sqrt(1 + m[0][0] - m[1][1] - m[2][2])
        q = [k / 4, (m[0][1] + m[1][0]) / k, (m[0][2] + m[2][0]) / k, (m[2][1] - m[1][2]) / k]
    elif m[1][1] > m[2][2]:
        k = 2 * math.sqrt(1 + m[1][1] - m[0][0] - m[2][2])
        q = [(m[0][1] + m[1][0]) / k, k / 4, (m[1][2] + m[2][1]) / k, (m[0][2] - m[2][0]) / k]
    else:
        k = 2 * math.sqrt(1 + m[2][2] - m[0][0] - m[1][1])
        q = [(m[0][2] + m[2][0]) / k, (m[1][2] + m[2][1]) / k, k / 4, (m[1][0] - m[0][1]) / k]
    n = math.sqrt(sum(x * x for x in q))
    return [x / n for x in q]


def build_glb(camera, boxes, objects, source):
    pos, nrm, idx = cube()
    bin_ = bytearray()
    bin_ += struct.pack("<%df" % (3 * len(pos)), *[x for p in pos for x in p])
    nrm_off = len(bin_)
    bin_ += struct.pack("<%df" % (3 * len(nrm)), *[x for n in nrm for x in n])
    idx_off = len(bin_)
    bin_ += struct.pack("<%dH" % len(idx), *idx)
    bin_len = len(bin_)
    while len(bin_) % 4:
        bin_ += b"\0"

    nodes, worst = [], 0.0
    for i, o in enumerate(objects):
        c, s, err = centre_size(o)
        worst = max(worst, err)
        nodes.append({"name": "obj_%d" % i, "mesh": 0, "translation": c, "scale": s})
    for k, b in enumerate(boxes):
        c, s, err = centre_size(b)
        worst = max(worst, err)
        nodes.append({"name": "OCC_%d" % k, "mesh": 0, "translation": c, "scale": s})
    nodes.append({"name": "camera", "camera": 0, "translation": camera["eye"],
                  "rotation": look_at_quat(camera["eye"], camera["target"], camera["up"])})

    gltf = {
        "asset": {"version": "2.0", "generator": "vantage tests/bench/city_scene_glb.py",
                  "extras": {"source": source, "objects": len(objects), "occluder_boxes": len(boxes),
                             "camera": camera}},
        "scene": 0,
        "scenes": [{"name": "city_scene", "nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": [{"name": "unit_cube", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2,
                                                         "mode": 4}]}],
        "cameras": [{"name": "street", "type": "perspective",
                     "perspective": {"yfov": math.radians(camera["fovy_deg"]), "aspectRatio": camera["aspect"],
                                     "znear": camera["near"], "zfar": camera["far"]}}],
        "buffers": [{"byteLength": bin_len}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": nrm_off, "target": 34962},
            {"buffer": 0, "byteOffset": nrm_off, "byteLength": idx_off - nrm_off, "target": 34962},
            {"buffer": 0, "byteOffset": idx_off, "byteLength": bin_len - idx_off, "target": 34963},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
             "min": [-0.5, -0.5, -0.5], "max": [0.5, 0.5, 0.5]},
            {"bufferView": 1, "componentType": 5126, "count": len(nrm), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "count": len(idx), "type": "SCALAR",
             "min": [0], "max": [len(pos) - 1]},
        ],
    }
    js = json.dumps(gltf, separators=(",", ":"), allow_nan=False).encode("utf-8")
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(bin_)
    out = bytearray(struct.pack("<4sII", b"glTF", 2, total))
    out += struct.pack("<I4s", len(js), b"JSON") + js
    out += struct.pack("<I4s", len(bin_), b"BIN\0") + bin_
    return bytes(out), worst


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description="Convert the city scene text file to a glTF 2.0 .glb level for "
                                             "`vantage import`.")
    ap.add_argument("--scene", default=os.path.join(here, "..", "data", "scenes", "city_scene.txt"),
                    help="the scene text file (default: tests/data/scenes/city_scene.txt)")
    ap.add_argument("--out", required=True, help="the .glb to write (its name is the sub-level's: "
                                                 "city_scene.glb -> city_scene)")
    a = ap.parse_args()
    camera, boxes, objects = read_scene(a.scene)
    glb, worst = build_glb(camera, boxes, objects, os.path.basename(a.scene))
    try:
        with open(a.out, "wb") as f:
            f.write(glb)
    except OSError as e:
        die("%s: %s" % (a.out, e.strerror))
    print("%s: %d test objects (nodes obj_0..obj_%d), %d occluder boxes (nodes OCC_0..OCC_%d), 1 cube mesh, "
          "%d bytes; box corners within %.3g m of the text file's" %
          (a.out, len(objects), len(objects) - 1, len(boxes), len(boxes) - 1, len(glb), worst))
    e, t = camera["eye"], camera["target"]
    print("scene camera: vantage query --eye %.9g,%.9g,%.9g --at %.9g,%.9g,%.9g --fov %.9g --near %.9g --far %.9g" %
          (e[0], e[1], e[2], t[0], t[1], t[2], camera["fovy_deg"], camera["near"], camera["far"]))


if __name__ == "__main__":
    main()
