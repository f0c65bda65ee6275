#!/usr/bin/env python3
"""Writes the seed-*.gltf / seed-*.glb files of tests/fuzz/corpus/gltf/:
the test levels of tests/data/ without their indentation, and small levels
made here that each exercise one convention or one corner of the importer (client/import/import_walk.c)
(instancing, mirroring, OCC_ pairing and merging, lights under scaled
nodes, spot cones, primitive modes, index types, sparse accessors, a
matrix transform, a deep tree, binary glTF, glTF 1.0, the scene model's
materials: textures embedded as PNG and JPEG with samplers and
KHR_texture_transform, KHR_materials_emissive_strength, UVs and tangents,
a directional light as the sun).

    python3 tests/fuzz/gen_gltf_seeds.py [OUT_DIR]
"""
import json, math, os, struct, sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data"))
from make_levels import Doc, box_mesh, quad_mesh, yaw  # noqa: E402


def compact(g):
    return json.dumps(g, separators=(",", ":")).encode()


def finish(d):
    """The document with its buffer as a data: URI (Doc.write without the file)."""
    import base64
    d.g["buffers"] = [{"byteLength": len(d.bin),
                       "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(d.bin)).decode()}]
    return d.g


def glb(d):
    """The document as binary glTF: JSON chunk, then the BIN chunk."""
    g = dict(d.g)
    g["buffers"] = [{"byteLength": len(d.bin)}]
    js = compact(g)
    js += b" " * (-len(js) % 4)
    bn = bytes(d.bin) + b"\0" * (-len(d.bin) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(bn), 0x004E4942) + bn
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def tri_doc():
    d = Doc()
    tri = d.mesh("tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 0, 1)] * 3, [0, 1, 2])
    d.node(name="tri", mesh=tri)
    return d


def lights_doc(scale):
    """Lights under a chain of scaled nodes: their directions must stay unit.
    (A mesh too: assimp calls a scene without meshes incomplete.)"""
    d = tri_doc()
    d.g["extensionsUsed"] = ["KHR_lights_punctual"]
    d.g["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"name": "p", "type": "point", "intensity": 10},
        {"name": "s", "type": "spot", "intensity": 100, "range": 5,
         "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.7}},
        {"name": "dim", "type": "point", "intensity": 0},
        {"name": "c", "type": "spot", "color": [0, 0, 2], "intensity": 1e30,
         "spot": {"innerConeAngle": 0, "outerConeAngle": 1.5707963}}]}}
    leaf = d.node(root=False, name="s", rotation=[0.3826834, 0, 0, 0.9238795],
                  extensions={"KHR_lights_punctual": {"light": 1}})
    for _ in range(6):
        leaf = d.node(root=False, name="g", scale=[scale, scale, scale], children=[leaf])
    d.g["scenes"][0]["nodes"].append(leaf)
    d.node(name="p", translation=[1, 2, 3], extensions={"KHR_lights_punctual": {"light": 0}})
    d.node(name="dim", extensions={"KHR_lights_punctual": {"light": 2}})
    d.node(name="c", scale=[0, 1, 1], extensions={"KHR_lights_punctual": {"light": 3}})
    return d


def occluders_doc():
    d = Doc()
    box = d.mesh("box", *box_mesh())
    wall = d.mesh("wall", *quad_mesh())
    d.node(name="hall", mesh=box, scale=[4, 4, 4], extras={"vantage_occluder": True})
    d.node(name="OCC_hall", mesh=wall, translation=[0, 0, 4])            # merges into hall's own
    d.node(name="gate", mesh=wall, translation=[10, 0, 0])
    d.node(name="OCC_gate", mesh=wall, translation=[10, 0, 0])
    d.node(name="occ_gate", mesh=box, translation=[10, 0, 1])            # OCC_ is case-blind: merges
    d.node(name="gate", mesh=box, translation=[20, 0, 0])                # a second "gate": the first keeps the name
    d.node(name="OCC_", mesh=wall)                                       # empty entity name
    d.node(name="OCC_nobody", mesh=wall, translation=[0, 0, -9])
    d.node(name="door", mesh=box, extras={"vantage_dynamic": True, "vantage_occluder": True})
    return d


def instances_doc():
    d = Doc()
    box = d.mesh("box", *box_mesh())
    wall = d.mesh("wall", *quad_mesh())
    for i in range(6):
        d.node(name="b%d" % i, mesh=box, translation=[i * 3, 0, 0], rotation=yaw(90 * (i % 2)))
    d.node(name="mirror", mesh=box, scale=[-1, 1, 1])                    # winding turns over
    d.node(name="skew", matrix=[1, 0, 0, 0, 0.5, 1, 0, 0, 0, 0, 1, 0, 7, 8, 9, 1], mesh=wall)
    d.g["meshes"].append({"name": "both", "primitives": d.g["meshes"][box]["primitives"] +
                          d.g["meshes"][wall]["primitives"]})
    d.node(name="two_prims", mesh=len(d.g["meshes"]) - 1, translation=[0, 10, 0])
    return d


def modes_doc():
    """Strips, fans, lines with triangles, u8 and u16 indices, no normals, no indices."""
    d = Doc()
    pos = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0), (2, 0, 1)]
    pv = d.view(b"".join(struct.pack("<3f", *p) for p in pos), 34962)
    acc = d.g["accessors"]
    acc.append({"bufferView": pv, "componentType": 5126, "count": len(pos), "type": "VEC3",
                "min": [0, 0, 0], "max": [2, 1, 1]})
    i8 = d.view(bytes([0, 1, 2, 3, 4]), 34963)
    acc.append({"bufferView": i8, "componentType": 5121, "count": 5, "type": "SCALAR"})
    i16 = d.view(struct.pack("<6H", 0, 1, 2, 2, 1, 3), 34963)
    acc.append({"bufferView": i16, "componentType": 5123, "count": 6, "type": "SCALAR"})
    prims = [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 5},
             {"attributes": {"POSITION": 0}, "indices": 1, "mode": 6},
             {"attributes": {"POSITION": 0}, "indices": 2, "mode": 4},
             {"attributes": {"POSITION": 0}, "indices": 2, "mode": 1},
             {"attributes": {"POSITION": 0}, "mode": 3},
             {"attributes": {"POSITION": 0}}]
    for k, p in enumerate(prims):
        if p.get("mode") in (1, 3): continue  # a node of only lines fails the import
        d.g["meshes"].append({"name": "m%d" % k, "primitives": [p]})
        d.node(name="n%d" % k, mesh=len(d.g["meshes"]) - 1, translation=[0, 0, k])
    d.g["meshes"].append({"name": "mixed", "primitives": [prims[2], prims[3], prims[4]]})
    d.node(name="mixed", mesh=len(d.g["meshes"]) - 1)
    return d


def sparse_doc():
    d = Doc()
    pos = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    pv = d.view(b"".join(struct.pack("<3f", *p) for p in pos), 34962)
    si = d.view(struct.pack("<H", 2), None)
    sv = d.view(struct.pack("<3f", 0, 1e13, 0), None)
    d.g["bufferViews"][si].pop("target")
    d.g["bufferViews"][sv].pop("target")
    d.g["accessors"].append({"bufferView": pv, "componentType": 5126, "count": 3, "type": "VEC3",
                             "min": [0, 0, 0], "max": [1, 1e13, 0],
                             "sparse": {"count": 1, "indices": {"bufferView": si, "componentType": 5123},
                                        "values": {"bufferView": sv}}})
    d.g["meshes"].append({"name": "far", "primitives": [{"attributes": {"POSITION": 0}}]})
    d.node(name="far", mesh=0)
    return d


def tiny_png():
    """A 2x2 RGBA PNG, written by hand (zlib)."""
    import zlib
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)
    raw = b"".join(b"\0" + bytes([40 * x + 10 * y, 200, 90, 255]) * 1 + bytes([99, 1, 2, 255]) for y in range(2)
                   for x in range(1))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 6, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def materials_doc():
    """Two materials, two embedded images (a PNG in the buffer, a JPEG's
    first bytes as a data: URI: the importer checks only the magic), a box
    with UVs and tangents placed mirrored and turned, a sun and a bulb."""
    import base64
    d = Doc()
    pos, nrm, idx = box_mesh()
    box = d.mesh("box", pos, nrm, idx)
    acc = d.g["accessors"]
    uv = d.view(b"".join(struct.pack("<2f", (i % 4) * 0.25, (i % 3) * 0.5) for i in range(len(pos))), 34962)
    acc.append({"bufferView": uv, "componentType": 5126, "count": len(pos), "type": "VEC2"})
    tg = d.view(b"".join(struct.pack("<4f", 1, 0, 0, -1 if i % 2 else 1) for i in range(len(pos))), 34962)
    acc.append({"bufferView": tg, "componentType": 5126, "count": len(pos), "type": "VEC4"})
    prim = d.g["meshes"][box]["primitives"][0]
    prim["attributes"]["TEXCOORD_0"] = len(acc) - 2
    prim["attributes"]["TANGENT"] = len(acc) - 1
    prim["material"] = 0
    wall = d.mesh("wall", *quad_mesh())
    d.g["meshes"][wall]["primitives"][0]["material"] = 1
    png = d.view(tiny_png(), None)
    d.g["bufferViews"][png].pop("target")
    jpg = b"\xff\xd8\xff\xe0" + b"\0" * 12 + b"\xff\xd9"
    d.g["images"] = [{"bufferView": png, "mimeType": "image/png"},
                     {"uri": "data:image/jpeg;base64," + base64.b64encode(jpg).decode()}]
    d.g["samplers"] = [{"wrapS": 33071, "wrapT": 33648, "minFilter": 9984, "magFilter": 9728}, {}]
    d.g["textures"] = [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 1}]
    tt = {"KHR_texture_transform": {"offset": [0.5, 0.25], "scale": [2, 0.5], "rotation": 1.2}}
    d.g["materials"] = [
        {"name": "a", "pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0.25, 1], "metallicFactor": 0,
                                               "baseColorTexture": {"index": 0, "extensions": tt},
                                               "metallicRoughnessTexture": {"index": 1}},
         "normalTexture": {"index": 1, "scale": 2}, "emissiveTexture": {"index": 0},
         "emissiveFactor": [1, 1, 0.5], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 7}},
         "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": True},
        {"name": "b", "alphaMode": "BLEND"}]
    d.g["extensionsUsed"] = ["KHR_lights_punctual", "KHR_texture_transform", "KHR_materials_emissive_strength"]
    d.g["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"name": "sun", "type": "directional", "color": [1, 0.9, 0.7], "intensity": 80000},
        {"name": "moon", "type": "directional", "intensity": 0.1},
        {"name": "bulb", "type": "point", "intensity": 30, "range": 9}]}}
    d.node(name="box", mesh=box, translation=[1, 2, 3], rotation=yaw(30), scale=[-1, 2, 0.5])
    d.node(name="wall", mesh=wall, translation=[0, 0, -5], scale=[3, 3, 3])
    d.node(name="sun", rotation=[-0.5, 0, 0, 0.8660254], extensions={"KHR_lights_punctual": {"light": 0}})
    d.node(name="moon", extensions={"KHR_lights_punctual": {"light": 1}})
    d.node(name="bulb", translation=[0, 5, 0], extensions={"KHR_lights_punctual": {"light": 2}})
    return d


def deep_doc(depth):
    d = tri_doc()
    top = 0
    for _ in range(depth):
        top = d.node(root=False, name="up", children=[top], translation=[0, 1, 0])
    d.g["scenes"][0]["nodes"] = [top]
    return d


def gltf1():
    return {"asset": {"version": "1.0"}, "scene": "s", "scenes": {"s": {"nodes": ["n"]}},
            "nodes": {"n": {"name": "n", "children": [], "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}}}


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                               "corpus", "gltf")
    os.makedirs(out, exist_ok=True)
    files = {}
    data = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data")
    for name in sorted(os.listdir(data)):
        if name.endswith(".gltf"):
            with open(os.path.join(data, name)) as f:
                files["seed-data-" + name] = compact(json.load(f))
    files["seed-tri.gltf"] = compact(finish(tri_doc()))
    files["seed-tri.glb"] = glb(tri_doc())
    files["seed-lights-big.gltf"] = compact(finish(lights_doc(1e30)))
    files["seed-lights-small.gltf"] = compact(finish(lights_doc(1e-30)))
    files["seed-occluders.gltf"] = compact(finish(occluders_doc()))
    files["seed-occluders.glb"] = glb(occluders_doc())
    files["seed-instances.gltf"] = compact(finish(instances_doc()))
    files["seed-modes.gltf"] = compact(finish(modes_doc()))
    files["seed-sparse.gltf"] = compact(finish(sparse_doc()))
    files["seed-deep-256.gltf"] = compact(finish(deep_doc(256)))
    files["seed-deep-257.gltf"] = compact(finish(deep_doc(257)))
    files["seed-v1.gltf"] = compact(gltf1())
    files["seed-materials.gltf"] = compact(finish(materials_doc()))
    files["seed-materials.glb"] = glb(materials_doc())
    for name, blob in sorted(files.items()):
        with open(os.path.join(out, name), "wb") as f:
            f.write(blob)
        print("%s: %d bytes" % (name, len(blob)))


if __name__ == "__main__":
    main()
