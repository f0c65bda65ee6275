#!/usr/bin/env python3
"""Authors the glTF 2.0 levels the import tests read (tests/data/*.gltf),
and, with --big N OUT [MESHES], a level of N instanced boxes for the load
benchmark (a grid 4 m apart from x = 5000 m: away from the demo city),
sharing MESHES meshes (1).

Conventions exercised (README "Authoring levels"): every node with a mesh
is an entity; a node named OCC_<name> is an occluder only, attached to the
entity node <name>; extras {"vantage_occluder": true} make a node both an
entity and its own occluder; extras {"vantage_dynamic": true} a dynamic
entity; KHR_lights_punctual point and spot lights.
"""
import base64, json, math, struct, sys

def box_mesh():
    # 24 vertices (flat normals per face), 36 indices, unit box -1..1
    faces = [((1,0,0),(0,1,0),(0,0,1)), ((-1,0,0),(0,0,1),(0,1,0)),
             ((0,1,0),(0,0,1),(1,0,0)), ((0,-1,0),(1,0,0),(0,0,1)),
             ((0,0,1),(1,0,0),(0,1,0)), ((0,0,-1),(0,1,0),(1,0,0))]
    pos, nrm, idx = [], [], []
    for n, u, v in faces:
        base = len(pos)
        for su, sv in ((-1,-1),(1,-1),(1,1),(-1,1)):
            pos.append(tuple(n[k] + su*u[k] + sv*v[k] for k in range(3)))
            nrm.append(n)
        # counter-clockwise seen from outside: (u x v) = n
        idx += [base, base+1, base+2, base, base+2, base+3]
    return pos, nrm, idx

def quad_mesh():
    # a 1x1 wall in the XY plane facing +Z (two triangles)
    pos = [(-1,-1,0),(1,-1,0),(1,1,0),(-1,1,0)]
    return pos, [(0,0,1)]*4, [0,1,2,0,2,3]

class Doc:
    def __init__(self):
        self.bin = bytearray()
        self.g = {"asset": {"version": "2.0", "generator": "vantage make_levels.py"},
                  "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [],
                  "accessors": [], "bufferViews": [], "buffers": []}

    def view(self, data, target):
        while len(self.bin) % 4: self.bin.append(0)
        off = len(self.bin)
        self.bin += data
        self.g["bufferViews"].append({"buffer": 0, "byteOffset": off, "byteLength": len(data), "target": target})
        return len(self.g["bufferViews"]) - 1

    def mesh(self, name, pos, nrm, idx, mode=4):
        pv = self.view(b"".join(struct.pack("<3f", *p) for p in pos), 34962)
        nv = self.view(b"".join(struct.pack("<3f", *p) for p in nrm), 34962)
        iv = self.view(b"".join(struct.pack("<I", i) for i in idx), 34963)
        acc = self.g["accessors"]
        lo = [min(p[k] for p in pos) for k in range(3)]
        hi = [max(p[k] for p in pos) for k in range(3)]
        acc.append({"bufferView": pv, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": lo, "max": hi})
        acc.append({"bufferView": nv, "componentType": 5126, "count": len(nrm), "type": "VEC3"})
        acc.append({"bufferView": iv, "componentType": 5125, "count": len(idx), "type": "SCALAR"})
        a = len(acc)
        self.g["meshes"].append({"name": name, "primitives": [{"attributes": {"POSITION": a-3, "NORMAL": a-2},
                                                              "indices": a-1, "mode": mode}]})
        return len(self.g["meshes"]) - 1

    def node(self, root=True, **kw):
        self.g["nodes"].append(kw)
        i = len(self.g["nodes"]) - 1
        if root: self.g["scenes"][0]["nodes"].append(i)
        return i

    def write(self, path):
        self.g["buffers"] = [{"byteLength": len(self.bin),
                              "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode()}]
        with open(path, "w") as f:
            json.dump(self.g, f, indent=1)

def yaw(deg):
    a = math.radians(deg) / 2
    return [0, math.sin(a), 0, math.cos(a)]

def small(path):
    d = Doc()
    box = d.mesh("box", *box_mesh())
    wall = d.mesh("wall", *quad_mesh())
    # 1..4: plain boxes (two share a rotation: one class for both)
    d.node(name="crate_a", mesh=box, translation=[0, 1, 0])
    d.node(name="crate_b", mesh=box, translation=[10, 1, 0])
    d.node(name="crate_c", mesh=box, translation=[0, 1, 10], rotation=yaw(45), scale=[2, 1, 1])
    d.node(name="crate_d", mesh=box, translation=[10, 1, 10], rotation=yaw(45), scale=[2, 1, 1])
    # 5: a dynamic one
    d.node(name="cart", mesh=box, translation=[-10, 0.5, 0], scale=[1, 0.5, 2], extras={"vantage_dynamic": True})
    # 6: a building that is its own occluder
    d.node(name="tower", mesh=box, translation=[0, 10, -30], scale=[5, 10, 5], extras={"vantage_occluder": True})
    # 7 + occluder: a wall entity with a separate, simpler occluder
    d.node(name="wall", mesh=wall, translation=[0, 5, 20], scale=[10, 5, 1])
    d.node(name="OCC_wall", mesh=wall, translation=[0, 5, 20], scale=[9.5, 4.5, 1])
    # 8: a group whose child carries the mesh: transforms compose
    child = d.node(root=False, name="lamp_post", mesh=box, translation=[0, 2, 0], scale=[0.2, 2, 0.2])
    d.node(name="street", translation=[20, 0, 20], rotation=yaw(90), children=[child])
    # an occluder with no entity of its name
    d.node(name="OCC_hill", mesh=box, translation=[50, -5, 50], scale=[20, 5, 20])
    # lights
    d.g["extensionsUsed"] = ["KHR_lights_punctual"]
    d.g["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"name": "sun", "type": "directional", "intensity": 3},
        {"name": "bulb", "type": "point", "color": [1, 0.8, 0.6], "intensity": 200, "range": 25},
        {"name": "spot", "type": "spot", "intensity": 500, "range": 40,
         "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.6}}]}}
    d.node(name="bulb", translation=[5, 4, 5], extensions={"KHR_lights_punctual": {"light": 1}})
    # a spot pointing straight down (glTF lights shine along -Z)
    d.node(name="spot", translation=[0, 12, 0], rotation=[-math.sin(math.pi / 4), 0, 0, math.cos(math.pi / 4)],
           extensions={"KHR_lights_punctual": {"light": 2}})
    d.node(name="sun", rotation=yaw(30), extensions={"KHR_lights_punctual": {"light": 0}})
    d.write(path)

def bad(path, kind):
    d = Doc()
    box = d.mesh("box", *box_mesh())
    d.node(name="ok", mesh=box, translation=[0, 1, 0])
    if kind == "huge":
        d.node(name="vast", mesh=box, scale=[1e30, 1, 1])
    elif kind == "occ_far":
        d.node(name="OCC_far", mesh=box, translation=[1e15, 0, 0])
    elif kind == "zero":
        d.node(name="flat", mesh=box, scale=[1, 0, 1])
    elif kind == "points":
        pts = d.mesh("dots", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 0, 1)] * 3, [0, 1, 2], mode=0)
        d.node(name="dots", mesh=pts)
    d.write(path)

def long_names(path):
    # names past 64 bytes still pair an entity with its OCC_ node
    d = Doc()
    box = d.mesh("box", *box_mesh())
    name = "a_building_with_a_long_descriptive_name_from_the_artists_outliner_" * 2
    d.node(name=name, mesh=box, translation=[0, 5, 0], scale=[5, 5, 5])
    d.node(name=name[:-1] + "X", mesh=box, translation=[20, 5, 0], scale=[5, 5, 5])
    d.node(name="OCC_" + name, mesh=box, translation=[0, 5, 0], scale=[4.5, 4.5, 4.5])
    d.write(path)

def big(n, path, meshes=1):
    # meshes > 1: that many boxes of different proportions, node i using
    # mesh i % meshes (the import benchmark: 10k nodes sharing 20 meshes;
    # baked per rotation and scale, as the importer did before issue 19,
    # that is 320 classes)
    d = Doc()
    pos, nrm, idx = box_mesh()
    boxes = [d.mesh("box%d" % k, [(p[0] * (1 + 0.1 * k), p[1], p[2] * (1 + 0.05 * k)) for p in pos], nrm, idx)
             for k in range(meshes)] if meshes > 1 else [d.mesh("box", pos, nrm, idx)]
    side = int(math.ceil(math.sqrt(n)))
    for i in range(n):
        x, z = i % side, i // side
        if meshes == 1:
            d.node(name="b%d" % i, mesh=boxes[0], translation=[5000 + x * 4.0, 1, z * 4.0], rotation=yaw(90 * (i % 4)))
        else:  # each mesh in 4 rotations and 4 scales: 16 placements a mesh, as a level's props vary
            k = i // meshes
            d.node(name="b%d" % i, mesh=boxes[i % meshes], translation=[5000 + x * 4.0, 1, z * 4.0],
                   rotation=yaw(90 * (k % 4)), scale=[1 + 0.25 * ((k // 4) % 4)] * 3)
    d.write(path)

if __name__ == "__main__":
    if len(sys.argv) in (4, 5) and sys.argv[1] == "--big":
        big(int(sys.argv[2]), sys.argv[3], int(sys.argv[4]) if len(sys.argv) == 5 else 1)
    else:
        out = sys.argv[1] if len(sys.argv) > 1 else "tests/data"
        small(out + "/level_small.gltf")
        long_names(out + "/level_names.gltf")
        for k in ("huge", "zero", "points", "occ_far"):
            bad(out + "/bad_%s.gltf" % k, k)
