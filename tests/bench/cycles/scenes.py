#!/usr/bin/env python3
"""scenes.py — the Cycles comparison's own scenes as small glTF 2.0 files
(JSON with the buffer and images embedded as data URIs), for `vantage
import`: unit meshes (a box, a UV sphere) placed by node transforms, glTF
metallic-roughness materials, and for the textured scene one procedural PNG
(a brick pattern with mortar lines, sRGB). Standard library only (the PNG
is written here with zlib), so it runs on any python3.

Usage: scenes.py boxes|textured OUT.gltf
"""
import base64
import json
import math
import struct
import sys
import zlib


def png_rgb(w, h, pix):
    """pix: bytes, w*h*3 RGB8 rows top-down -> PNG bytes."""
    raw = b"".join(b"\0" + pix[y * w * 3:(y + 1) * w * 3] for y in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def box_mesh():
    """-0.5..0.5 cube, 24 vertices (flat normals), UVs 0..1 per face."""
    pos, nrm, uv, idx = [], [], [], []
    faces = [((1, 0, 0), (0, 0, -1), (0, 1, 0)), ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
             ((0, 1, 0), (1, 0, 0), (0, 0, -1)), ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
             ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]
    for n, u, v in faces:
        b = len(pos)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            pos.append(tuple(0.5 * n[k] + 0.5 * su * u[k] + 0.5 * sv * v[k] for k in range(3)))
            nrm.append(n)
            uv.append(((su + 1) / 2, (1 - sv) / 2))
        idx += [b, b + 1, b + 2, b, b + 2, b + 3]
    return pos, nrm, uv, idx


def sphere_mesh(nu=48, nv=24):
    """unit-diameter UV sphere (radius 0.5), smooth normals."""
    pos, nrm, uv, idx = [], [], [], []
    for j in range(nv + 1):
        th = math.pi * j / nv
        for i in range(nu + 1):
            ph = 2 * math.pi * i / nu
            n = (math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph))
            pos.append(tuple(0.5 * c for c in n))
            nrm.append(n)
            uv.append((i / nu, j / nv))
    for j in range(nv):
        for i in range(nu):
            a, b = j * (nu + 1) + i, (j + 1) * (nu + 1) + i
            idx += [a, b, a + 1, a + 1, b, b + 1]
    return pos, nrm, uv, idx


class Gltf:
    def __init__(self):
        self.bin = bytearray()
        self.j = {"asset": {"version": "2.0", "generator": "vantage tests/bench/cycles/scenes.py"},
                  "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [], "materials": [],
                  "accessors": [], "bufferViews": [], "buffers": []}

    def _view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.j["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data),
                                      **({"target": target} if target else {})})
        self.bin += data
        return len(self.j["bufferViews"]) - 1

    def _acc(self, rows, typ, comp=5126, target=34962, minmax=False):
        n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[typ]
        fmt = "<%d%s" % (len(rows) * n, "f" if comp == 5126 else "I")
        flat = [x for r in rows for x in (r if n > 1 else (r,))]
        a = {"bufferView": self._view(struct.pack(fmt, *flat), target), "componentType": comp,
             "count": len(rows), "type": typ}
        if minmax:
            a["min"] = [min(r[k] for r in rows) for k in range(n)]
            a["max"] = [max(r[k] for r in rows) for k in range(n)]
        self.j["accessors"].append(a)
        return len(self.j["accessors"]) - 1

    def mesh(self, name, m, material):
        pos, nrm, uv, idx = m
        prim = {"attributes": {"POSITION": self._acc(pos, "VEC3", minmax=True), "NORMAL": self._acc(nrm, "VEC3"),
                               "TEXCOORD_0": self._acc(uv, "VEC2")},
                "indices": self._acc(idx, "SCALAR", 5125, 34963), "material": material}
        self.j["meshes"].append({"name": name, "primitives": [prim]})
        return len(self.j["meshes"]) - 1

    def material(self, name, base, metallic, roughness, tex=None):
        pbr = {"baseColorFactor": list(base) + [1.0], "metallicFactor": metallic, "roughnessFactor": roughness}
        if tex is not None:
            pbr["baseColorTexture"] = {"index": tex}
        self.j["materials"].append({"name": name, "pbrMetallicRoughness": pbr})
        return len(self.j["materials"]) - 1

    def texture_png(self, png):
        self.j.setdefault("images", []).append(
            {"uri": "data:image/png;base64," + base64.b64encode(png).decode()})
        self.j.setdefault("samplers", []).append({"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497})
        self.j.setdefault("textures", []).append({"sampler": 0, "source": len(self.j["images"]) - 1})
        return len(self.j["textures"]) - 1

    def node(self, name, mesh, t, s, yaw=0.0):
        q = [0.0, math.sin(math.radians(yaw) / 2), 0.0, math.cos(math.radians(yaw) / 2)]
        self.j["nodes"].append({"name": name, "mesh": mesh, "translation": list(t), "rotation": q, "scale": list(s)})
        self.j["scenes"][0]["nodes"].append(len(self.j["nodes"]) - 1)

    def write(self, path):
        self.j["buffers"] = [{"byteLength": len(self.bin),
                              "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode()}]
        with open(path, "w") as f:
            json.dump(self.j, f)


def bricks(w=256, h=256):
    """a running-bond brick wall: 8 courses, 4 bricks a course, mortar 4 px;
    each brick's red varies by a hash so the texture has low and high
    frequencies (what filtering differences show up in)."""
    pix = bytearray()
    ch, bw, mortar = h // 8, w // 4, 4
    for y in range(h):
        row, yy = y // ch, y % ch
        for x in range(w):
            xx = (x + (bw // 2 if row % 2 else 0)) % w
            col, xb = xx // bw, xx % bw
            if yy < mortar or xb < mortar:
                pix += bytes((200, 196, 186))
            else:
                k = (row * 7 + col * 13) % 5
                pix += bytes((150 + 15 * k, 62 + 6 * k, 44 + 3 * k))
    return png_rgb(w, h, bytes(pix))


def main():
    kind, out = sys.argv[1], sys.argv[2]
    g = Gltf()
    if kind == "boxes":
        # colours linear; one of each kind of surface the BRDF treats
        mats = [g.material("white_diffuse", (0.8, 0.8, 0.8), 0.0, 1.0),
                g.material("red_plastic", (0.7, 0.06, 0.05), 0.0, 0.4),
                g.material("gold_metal", (1.0, 0.77, 0.34), 1.0, 0.3),
                g.material("blue_glossy", (0.05, 0.15, 0.6), 0.0, 0.15),
                g.material("green_rough", (0.1, 0.45, 0.12), 0.0, 0.8)]
        box = [g.mesh("box_%d" % i, box_mesh(), m) for i, m in enumerate(mats[:4])]
        sph = {i: g.mesh("sphere_%d" % i, sphere_mesh(), mats[i]) for i in (2, 4)}
        g.node("box_white", box[0], (-4.0, 1.5, 0.0), (3.0, 3.0, 3.0), 20)
        g.node("box_red", box[1], (0.5, 1.0, -1.0), (2.0, 2.0, 2.0), -15)
        g.node("box_gold", box[2], (4.0, 0.75, 1.0), (1.5, 1.5, 1.5), 40)
        g.node("box_blue", box[3], (1.5, 2.5, -6.0), (5.0, 5.0, 2.0), 0)
        g.node("sphere_green", sph[4], (-1.5, 0.8, 3.0), (1.6, 1.6, 1.6))
        g.node("sphere_gold", sph[2], (2.2, 0.6, 3.5), (1.2, 1.2, 1.2))
    elif kind == "textured":
        t = g.texture_png(bricks())
        wall = g.material("brick", (1.0, 1.0, 1.0), 0.0, 0.9, t)
        mwall = g.mesh("wall", box_mesh(), wall)
        plain = g.mesh("slab", box_mesh(), g.material("concrete", (0.45, 0.44, 0.42), 0.0, 0.95))
        g.node("wall_left", mwall, (-3.0, 2.0, -2.0), (6.0, 4.0, 0.6), 30)
        g.node("wall_right", mwall, (3.5, 1.5, -1.0), (4.0, 3.0, 0.6), -35)
        g.node("cube", mwall, (0.0, 1.0, 2.0), (2.0, 2.0, 2.0), 10)
        g.node("slab", plain, (0.0, 0.1, 0.0), (14.0, 0.2, 10.0))
    else:
        sys.exit("scenes.py: unknown scene %s (boxes or textured)" % kind)
    g.write(out)


if __name__ == "__main__":
    main()
