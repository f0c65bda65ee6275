"""harness.py — what the headless-Blender tests share: a real vantaged
(started here with a --data-dir and a --tokens file, stopped with SIGTERM
and its exit checked), the project's own C CLI as the independent reader of
the daemon's state (`vantage export -` JSON lines, `vantage export x.glb`,
`vantage sublevel list --json`), Blender's own world matrices as the
reference, and a checker that names every disagreement.

Runs inside Blender (`blender -b --factory-startup --python FILE -- ...`);
the add-on is imported from client/blender. VANTAGE_BIN_DIR names the
binaries (default build/release).

Conventions the reference uses, written here independently of the add-on's
convert.py: a Blender point (x, y, z) is Vantage's (x, z, -y) (glTF's
Y-up mapping), so a world matrix M is C M C^T; a Vantage entity's matrix is
pos + R(q) diag(scale), R the usual unit-quaternion rotation.
"""
import json
import math
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time

import numpy
numpy.bool = bool  # Debian's numpy 1.24 lacks numpy.bool, which Blender 3.4's glTF importer uses
import numpy as np  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "client", "blender"))
BIN = os.path.abspath(os.path.join(ROOT, os.environ.get("VANTAGE_BIN_DIR", "build/release")))

EDITOR_TOKEN = "editor-token-0123456789abcdef"
VIEWER_TOKEN = "viewer-token-0123456789abcdef"
C = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])
OURS = 0x424C  # the add-on's entity id prefix (top 16 bits): README "Editor live-link"

FAILS = []


def check(cond, what):
    if not cond:
        FAILS.append(what)
        print("FAIL:", what, flush=True)
    return cond


class Daemon:
    def __init__(self, tmp):
        self.tmp = tmp
        self.sock = os.path.join(tmp, "vantaged.sock")
        self.data = os.path.join(tmp, "data")
        self.tokens = os.path.join(tmp, "tokens")
        with open(self.tokens, "w") as f:
            f.write("editor %s\nviewer %s\n" % (EDITOR_TOKEN, VIEWER_TOKEN))
        os.chmod(self.tokens, 0o600)
        self.proc = None

    def start(self):
        self.log = open(os.path.join(self.tmp, "vantaged.log"), "ab")
        self.proc = subprocess.Popen([os.path.join(BIN, "vantaged"), "--scene", "empty", "--bind", "", "--unix",
                                      self.sock, "--tokens", self.tokens, "--data-dir", self.data, "--threads", "1"],
                                     stdout=self.log, stderr=subprocess.STDOUT)
        end = time.monotonic() + 20
        while time.monotonic() < end:
            if self.proc.poll() is not None:
                raise RuntimeError("vantaged exited %d (log: %s)" % (self.proc.returncode, self.tmp))
            if os.path.exists(self.sock) and self.cli("stats", check_rc=False)[0] == 0:
                return
            time.sleep(0.05)
        raise RuntimeError("vantaged did not come up")

    def kill9(self):
        self.proc.kill()
        self.proc.wait()

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            rc = self.proc.wait(20)
            check(rc == 0, "vantaged exited %d on SIGTERM" % rc)

    def cli(self, *args, check_rc=True, token=VIEWER_TOKEN):
        r = subprocess.run([os.path.join(BIN, "vantage"), "-s", self.sock, "--token", token] + list(args),
                           capture_output=True, text=True, timeout=60)
        if check_rc and r.returncode != 0:
            raise RuntimeError("vantage %s: exit %d: %s" % (" ".join(args), r.returncode, r.stderr))
        return r.returncode, r.stdout, r.stderr

    def export_lines(self):
        out = self.cli("export", "-")[1]
        return [json.loads(line) for line in out.splitlines() if line.strip().startswith("{")]

    def export_glb(self):
        path = os.path.join(self.tmp, "scene.glb")
        self.cli("export", path)
        with open(path, "rb") as f:
            b = f.read()
        magic, ver, total = struct.unpack_from("<III", b)
        assert magic == 0x46546C67, "not a GLB"
        ln, kind = struct.unpack_from("<II", b, 12)
        g = json.loads(b[20:20 + ln].decode())
        off = 20 + ln
        g["_bin"] = b[off + 8:off + 8 + struct.unpack_from("<I", b, off)[0]] if off < len(b) else b""
        return g

    def stats(self):
        return json.loads(self.cli("stats", "--json")[1])

    def sublevels(self):
        out = self.cli("sublevel", "list", "--json")[1]
        return {s["name"]: s for s in (json.loads(line) for line in out.splitlines() if line.strip())}


def y_up(m):
    return C @ np.array(m, dtype=np.float64) @ C.T


def trs(pos, rot, scale):
    x, y, z, w = rot
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r @ np.diag(scale)
    m[:3, 3] = pos
    return m


def nearest_trs(m):
    """m itself when it is a rotation times a per-axis scale; with shear (a
    rotated child of a non-uniformly scaled parent) the nearest such matrix,
    which the add-on documents it sends: the rotation closest to the 3x3
    part (polar decomposition, by SVD; a mirror kept as a negative x scale)
    and the scale that fits along its axes"""
    a = m[:3, :3]
    f = np.diag([-1.0 if np.linalg.det(a) < 0 else 1.0, 1.0, 1.0])
    a2 = a @ f
    s = np.linalg.norm(a2, axis=0)
    r = a2 / s
    if np.max(np.abs(r.T @ r - np.eye(3))) <= 1e-9:
        return m
    u, _, vt = np.linalg.svd(a2)
    r = u @ vt
    out = m.copy()
    out[:3, :3] = r @ np.diag(np.diag(r.T @ a2)) @ f
    return out


def blender_entities(bpy):
    """{id: object} of what the add-on should mirror as entities: mesh
    objects in the view layer (not OCC_ occluder-only ones)"""
    out = {}
    for o in bpy.context.view_layer.objects:
        if o.type == 'MESH' and not o.name.upper().startswith("OCC_") and isinstance(o.get("vantage_id"), str):
            i = int(o["vantage_id"], 16)
            check(i not in out, "two live Blender objects share id %x: %s, %s" % (i, out.get(i), o.name))
            out[i] = o
    return out


def principled(m):
    b = next(n for n in m.node_tree.nodes if n.type == 'BSDF_PRINCIPLED')
    base = tuple(b.inputs["Base Color"].default_value)
    if b.inputs["Base Color"].is_linked:  # a texture is the colour: glTF's factor is 1 (it multiplies the texture)
        base = (1.0, 1.0, 1.0, base[3])
    return (base, b.inputs["Metallic"].default_value,
            b.inputs["Roughness"].default_value)


def check_converged(bpy, d, label, glb=True, refused=(), kept=()):
    """the daemon's state (read by the C CLI) equals Blender's: the same
    entity ids, once each; world transforms within 1e-5 relative; bounds;
    with glb the material factors and the set of the add-on's materials.
    refused: objects the add-on must not send; kept: material ids the
    daemon keeps though Blender no longer uses them (a removal refused)"""
    t0 = time.monotonic()
    lines = d.export_lines()
    ours = [e for e in lines if (e["id"] >> 48) == OURS]
    ids = [e["id"] for e in ours]
    want = {i: o for i, o in blender_entities(bpy).items() if o.name not in refused}
    ok = check(len(ids) == len(set(ids)), "%s: the export lists an id twice" % label)
    ok &= check(set(ids) == set(want), "%s: daemon has %d of ours, Blender %d (missing %d, extra %d)" %
                (label, len(set(ids)), len(want), len(set(want) - set(ids)), len(set(ids) - set(want))))
    worst = worst_box = 0.0
    for e in ours:
        o = want.get(e["id"])
        if o is None:
            continue
        ref = nearest_trs(y_up(o.matrix_world))
        got = trs(e["pos"], e["rot"], e["scale"])
        # 1e-5 relative: the daemon keeps rot and scale as f32 (2^-24 ~ 6e-8
        # a component, ~3e-7 after the products) and pos as f64; the scale
        # of the comparison is the matrix's largest element (at least 1 m)
        err = float(np.max(np.abs(got - ref))) / max(1.0, float(np.max(np.abs(ref))))
        worst = max(worst, err)
        if not check(err <= 1e-5, "%s: '%s' world transform off by %.3g relative" % (label, o.name, err)):
            ok = False
            break
        # the daemon's bounds, derived from the mesh the add-on sent and the
        # transform, against Blender's own box of the evaluated mesh (its
        # 8 corners through the world matrix): checks the vertices' axes and
        # the modifiers too. 1e-4 relative: the mesh is f32 and the daemon
        # rounds its bounds outward
        ev = o.evaluated_get(bpy.context.evaluated_depsgraph_get())
        corners = np.array([list(c) + [1.0] for c in ev.bound_box])
        w = (nearest_trs(y_up(o.matrix_world)) @ C @ corners.T).T[:, :3]  # corners to Y-up, then placed
        box = np.concatenate([w.min(0), w.max(0)])
        size = max(1.0, float(np.max(np.abs(box))))
        berr = float(np.max(np.abs(np.array(e["aabb"]) - box))) / size
        worst_box = max(worst_box, berr)
        if not check(berr <= 1e-4, "%s: '%s' bounds %s, Blender's %s" % (label, o.name, e["aabb"], box.tolist())):
            ok = False
            break
    if glb:
        g = d.export_glb()
        mats = {m["name"]: m for m in g.get("materials", [])}
        nm = 0
        for node in g["nodes"]:
            if not node.get("name", "").startswith("entity_") or "mesh" not in node:
                continue
            o = want.get(int(node["name"][7:]))
            if o is None or not o.material_slots or o.material_slots[0].material is None:
                continue
            bm = o.material_slots[0].material
            prim = g["meshes"][node["mesh"]]["primitives"][0]
            gm = g["materials"][prim["material"]] if "material" in prim else None
            if not check(gm is not None and gm["name"] == "material_%d" % int(bm["vantage_id"], 16),
                         "%s: '%s' has no material %s in the export" % (label, o.name, bm.name)):
                ok = False
                break
            base, met, rough = principled(bm)
            pbr = gm["pbrMetallicRoughness"]
            # f32 round trip: 1e-6
            if not check(max(abs(a - b) for a, b in zip(pbr["baseColorFactor"], base)) < 1e-6 and
                         abs(pbr["metallicFactor"] - met) < 1e-6 and abs(pbr["roughnessFactor"] - rough) < 1e-6,
                         "%s: '%s' material factors differ: %s vs %s" % (label, o.name, pbr, (base, met, rough))):
                ok = False
                break
            nm += 1
        # the same materials: the daemon's of the add-on's range (0xB1E00000 +
        # n) are those the mirrored objects use, no more
        theirs = {int(x["name"][9:]) for x in g.get("materials", []) if x["name"].startswith("material_")}
        theirs = {i for i in theirs if 0xB1E00000 <= i < 0xB1F00000}
        used = {int(o.material_slots[0].material["vantage_id"], 16) for o in want.values()
                if o.material_slots and o.material_slots[0].material is not None} | set(kept)
        ok &= check(theirs == used, "%s: the daemon holds materials %s, Blender's objects use %s" %
                    (label, sorted(theirs - used), sorted(used - theirs)))
        print("  %s: %d entities' materials and %d materials checked in the glb" % (label, nm, len(used)))
    print("  %s: %d entities, worst transform error %.2g, bounds %.2g, checked in %.2f s" %
          (label, len(ids), worst, worst_box, time.monotonic() - t0), flush=True)
    return ok


def tmpdir():
    return tempfile.mkdtemp(prefix="vantage-blender-")


def finish(d, tmp):
    if d is not None:
        d.stop()
    if FAILS:
        print("%d failure(s); daemon log in %s" % (len(FAILS), tmp))
        sys.stdout.flush()
        os._exit(1)
    shutil.rmtree(tmp, ignore_errors=True)
    print("ok")
    sys.stdout.flush()
    os._exit(0)


def run(main):
    """runs a test's main; an exception is a failure with its traceback
    (Blender would otherwise print it and exit 0)"""
    try:
        main()
    except Exception:
        import traceback
        traceback.print_exc()
        sys.stdout.flush()
        os._exit(1)
