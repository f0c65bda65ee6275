"""scene.py — Blender's scene as the daemon should hold it: builds
link.Desired snapshots and transforms on Blender's main thread (bpy is
touched nowhere else).

What it owns:
  * stable ids in custom properties (`vantage_id`, a hex string: Blender's
    integer properties are 32-bit): objects get ids in the entity range,
    materials and images in the material range, mesh datablocks (or objects
    with modifiers) a mesh class. A duplicated datablock carries its
    source's id: two live holders of one id are detected and the copy gets
    a new one (the holder seen before keeps it);
  * meshes: one mesh class per mesh datablock (an object with modifiers:
    one of its own), the evaluated mesh (modifiers applied), vertices
    split where normals or UVs differ, re-encoded only when Blender says
    its geometry changed and at most every MESH_MIN_INTERVAL seconds;
  * materials (Principled BSDF -> glTF metallic-roughness), image
    textures (the PNG/JPEG bytes), lights (point, spot; the first sun is
    the environment's sun), the world (colour or HDRI), collections as
    sub-levels, occluders (custom property `vantage_occluder`, or an object
    named OCC_<name>: the importer's rule);
  * what cannot be sent is said once per object, with its name and why.
"""
import math
import os
import random
import struct
import tempfile
import time

import bpy
import numpy as np

from . import codec, convert, link as lk

MESH_MIN_INTERVAL = 0.25  # seconds between re-uploads of one edited mesh
PROP = "vantage_id"
CLASS_PROP = "vantage_class"


def _rand_entity_id(used):
    while True:
        i = (lk.ENTITY_PREFIX << 48) | random.getrandbits(48)
        if i not in used and i & 0xFFFFFFFFFFFF:
            return i


class Ids:
    """id assignment and duplicate detection for one kind of datablock"""

    def __init__(self, prop, alloc, parse=lambda s: int(s, 16), fmt=lambda i: "%x" % i):
        self.prop, self.alloc, self.parse, self.fmt = prop, alloc, parse, fmt
        self.owner = {}  # id -> as_pointer() of the holder seen last time

    def assign(self, blocks, log):
        """{id: block} for `blocks`, giving new ids to those without one and
        to the copies of a duplicated one"""
        by_id, fresh = {}, []
        for b in blocks:
            v = b.get(self.prop)
            try:
                i = self.parse(v) if isinstance(v, (str, int)) else None
            except ValueError:
                i = None
            if i is None or not self.valid(i):
                fresh.append(b)
                continue
            by_id.setdefault(i, []).append(b)
        out = {}
        for i, holders in by_id.items():
            if len(holders) > 1:
                ptr = self.owner.get(i)
                keep = next((h for h in holders if h.as_pointer() == ptr), None)
                if keep is None:  # after an undo the pointers are new: the first name keeps it
                    keep = min(holders, key=lambda h: h.name)
                for h in holders:
                    if h is not keep:
                        fresh.append(h)
                holders = [keep]
            out[i] = holders[0]
        used = set(out)
        for b in sorted(fresh, key=lambda b: b.name):
            i = self.alloc(used)
            used.add(i)
            b[self.prop] = self.fmt(i)
            out[i] = b
        self.owner = {i: b.as_pointer() for i, b in out.items()}
        return out

    def valid(self, i):
        return True


class EntityIds(Ids):
    def __init__(self):
        super().__init__(PROP, _rand_entity_id)

    def valid(self, i):
        return lk.owned_entity(i)


def _alloc_range(base, span):
    def alloc(used):
        for k in range(span):
            if base + k not in used and k:
                return base + k
        raise RuntimeError("no free id in the add-on's range")
    return alloc


class MaterialIds(Ids):
    def __init__(self):
        super().__init__(PROP, _alloc_range(lk.MATERIAL_BASE, lk.MATERIAL_SPAN))

    def valid(self, i):
        return lk.owned_material(i) and i != lk.MATERIAL_BASE


class ClassIds(Ids):
    def __init__(self):
        super().__init__(CLASS_PROP, _alloc_range(lk.CLASS_BASE, lk.CLASS_SPAN), parse=int, fmt=int)

    def valid(self, i):
        return lk.owned_class(i) and i != lk.CLASS_BASE


def all_world_matrices():
    """(n, 4, 4) world matrices of bpy.data.objects, in its order, rows as
    mathutils gives them: one foreach_get for all objects (Blender keeps
    them as float32, column by column) instead of ~20 us an object
    converting Matrix objects"""
    objs = bpy.data.objects
    buf = np.empty(len(objs) * 16, np.float32)
    objs.foreach_get("matrix_world", buf)
    return buf.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)


class Builder:
    """the state that outlives one snapshot: ids, encoded meshes, image bytes,
    what was already reported"""

    def __init__(self, log, limits):
        self.log = log
        self.limits = limits  # dict(max_payload, max_batch) from HELLO_OK (defaults until connected)
        self.ent_ids, self.mat_ids, self.img_ids, self.class_ids = EntityIds(), MaterialIds(), MaterialIds(), ClassIds()
        self.meshes = {}      # class -> (payload or None, key, time encoded)
        self.mesh_dirty = set()  # mesh keys (("mesh", name) or ("obj", name)) Blender says changed
        self.images = {}      # image name -> (signature, (fmt, flags, bytes))
        self.said = set()     # (name, why) reported once
        self.names = {}       # entity id -> object name (the last snapshot's)
        self.obj_ids = {}     # object name -> entity id
        self.shear_said = set()
        self.mesh_retry = 0.0  # monotonic time a rate-limited mesh edit is due (0: none)

    def say(self, name, why):
        if (name, why) not in self.said:
            self.said.add((name, why))
            self.log("'%s': %s" % (name, why), error=True)

    # ---- transforms -------------------------------------------------------------
    def trs_many(self, objs, mats):
        """trs for many objects at once (convert.decompose_many), mats their
        world matrices (all_world_matrices()[indices]): a drag"""
        out = []
        for o, (pos, rot, scale, err, why) in zip(objs, convert.decompose_many(mats)):
            if why:
                self.say(o.name, why + ": not sent")
                out.append(None)
                continue
            if err > 1e-6 and o.name not in self.shear_said:
                self.shear_said.add(o.name)
                self.log("'%s': its world matrix has shear (a non-uniformly scaled parent): sent the nearest "
                         "position, rotation and scale (%.2g relative off)" % (o.name, err))
            out.append((pos, rot, scale))
        return out

    # ---- the full snapshot --------------------------------------------------------
    def build(self, scene, view_layer, depsgraph):
        d = lk.Desired()
        excluded_colls = set()

        def walk(lc, parent_excluded):
            ex = parent_excluded or lc.exclude
            if ex and lc.collection is not scene.collection:
                excluded_colls.add(lc.collection.name)
            for ch in lc.children:
                walk(ch, ex)
        walk(view_layer.layer_collection, False)
        d.excluded = {lk.SUBLEVEL_PREFIX + n for n in excluded_colls}

        all_objs = list(scene.objects)
        # each object's collection, in one pass (Object.users_collection
        # scans every collection per call); the scene's own first
        coll_of = {}
        stack = [scene.collection]
        while stack:  # (Collection.children_recursive is Blender 3.1 on)
            c = stack.pop(0)
            for o in c.objects:
                coll_of.setdefault(o.name, c)
            stack.extend(c.children)
        # world transforms of all mesh objects at once
        index = {o.name: k for k, o in enumerate(bpy.data.objects)}
        mesh_objs = [o for o in all_objs if o.type == 'MESH']
        mats = all_world_matrices()
        trs_of = dict(zip((o.name for o in mesh_objs),
                          self.trs_many(mesh_objs, mats[[index[o.name] for o in mesh_objs]]) if mesh_objs else []))
        ids = self.ent_ids.assign(all_objs, self.log)
        self.obj_ids = {o.name: i for i, o in ids.items()}
        self.names = {i: o.name for i, o in ids.items()}
        live = set(o.name for o in view_layer.objects)
        mats = [m for m in bpy.data.materials if m.users]
        mat_ids = self.mat_ids.assign(mats, self.log)
        mat_of = {m.name: i for i, m in mat_ids.items()}
        sun = None
        occ_named = []
        holders = {}
        for o in all_objs:
            if o.type == 'MESH' and o.name in live and not o.name.upper().startswith("OCC_"):
                h = o if len(o.modifiers) else o.data
                holders[h.as_pointer()] = h
        cls_of = {h.as_pointer(): c for c, h in self.class_ids.assign(list(holders.values()), self.log).items()}
        for i, o in ids.items():
            if o.name not in live:
                continue
            coll = coll_of.get(o.name, scene.collection)
            sub = "" if coll is scene.collection else lk.SUBLEVEL_PREFIX + coll.name
            if o.type == 'LIGHT':
                if o.data.type == 'SUN':
                    if sun is None:
                        sun = o
                    else:
                        self.say(o.name, "a second sun: Vantage has one (the environment's); '%s' is used" % sun.name)
                    continue
                rec = self.light(i, o)
                if rec is not None:
                    d.lights[i] = (sub, rec)
                continue
            if o.type != 'MESH':
                continue
            if o.name.upper().startswith("OCC_"):
                occ_named.append((i, o))
                continue
            cls = self.mesh_class(o, cls_of[(o if len(o.modifiers) else o.data).as_pointer()], depsgraph)
            if cls is None:
                continue
            t = trs_of.get(o.name)
            if t is None:
                continue
            mat = 0
            if o.material_slots and o.material_slots[0].material is not None:
                mat = mat_of.get(o.material_slots[0].material.name, 0)
            flags = codec.ENT_TRANSFORM | (codec.ENT_DYNAMIC if o.get("vantage_dynamic") else 0)
            d.ents[i] = dict(class_id=cls, sub=sub, flags=flags, material=mat, pos=t[0], rot=t[1], scale=t[2])
            if o.get("vantage_occluder"):
                p = self.occluder(i, o, depsgraph, None)
                if p is not None:
                    d.occluders[i] = p
        for c, (payload, key, _) in self.meshes.items():
            if payload is not None and any(e["class_id"] == c for e in d.ents.values()):
                d.meshes[c] = payload
        for i, o in occ_named:
            target = bpy.data.objects.get(o.name[4:])
            tid = self.obj_ids.get(target.name) if target is not None else None
            if tid in d.ents:
                p = self.occluder(tid, o, depsgraph, target)
                if p is not None:
                    d.occluders[tid] = p
            else:
                p = self.occluder(i, o, depsgraph, None, world=True)
                if p is not None:
                    d.occluders[i] = p
        used_mats = {e["material"] for e in d.ents.values()}
        img_ids = self.img_ids.assign([im for im in bpy.data.images if im.users and im.type == 'IMAGE'], self.log)
        img_of = {im.name: i for i, im in img_ids.items()}
        for mid, m in mat_ids.items():
            if mid in used_mats:
                d.materials[mid] = self.material(mid, m, img_of, d.textures)
        d.env = self.environment(scene, sun, img_of, d.textures)
        return d

    # ---- meshes ---------------------------------------------------------------------
    def mesh_class(self, o, cls, depsgraph):
        """(re-)encodes the object's mesh for class `cls` when Blender changed
        it (at most every MESH_MIN_INTERVAL); returns cls, or None when the
        mesh cannot be sent (said once)"""
        key = ("obj", o.name) if len(o.modifiers) else ("mesh", o.data.name)
        old = self.meshes.get(cls)
        now = time.monotonic()
        if old is not None and old[1] == key and key not in self.mesh_dirty:
            return cls if old[0] is not None else None
        if old is not None and old[1] == key and now - old[2] < MESH_MIN_INTERVAL:
            # rate-limited: the snapshot the mirror takes at mesh_retry sends it
            due = old[2] + MESH_MIN_INTERVAL
            self.mesh_retry = min(self.mesh_retry or due, due)
            return cls if old[0] is not None else None
        self.mesh_dirty.discard(key)
        payload = self.encode_mesh(o, cls, depsgraph)
        self.meshes[cls] = (payload, key, now)
        return cls if payload is not None else None

    def encode_mesh(self, o, cls, depsgraph):
        mb = self.limits["max_batch"]
        maxp = self.limits["max_payload"]
        src = o.data
        # cheap refusal first: a mesh over the daemon's limits is not evaluated
        nv = len(src.vertices)
        lt = np.empty(len(src.polygons), np.int32)
        src.polygons.foreach_get("loop_total", lt)
        nt = int(np.sum(lt - 2)) if len(lt) else 0
        if nv > mb or nt > mb:
            self.say(o.name, "its mesh '%s' has %d vertices and %d triangles: over the daemon's limits (%d vertices "
                     "and %d triangles a mesh class, %d bytes a message): not sent" % (src.name, nv, nt, mb, mb, maxp))
            return None
        ev = o.evaluated_get(depsgraph)
        me = ev.to_mesh()
        try:
            me.calc_loop_triangles()
            ntri = len(me.loop_triangles)
            if ntri == 0:
                self.say(o.name, "its mesh has no faces: not sent")
                return None
            if ntri > mb:
                self.say(o.name, "its evaluated mesh has %d triangles: over the daemon's %d a mesh class: not sent" %
                         (ntri, mb))
                return None
            if hasattr(me, "calc_normals_split"):
                me.calc_normals_split()
            nl = len(me.loops)
            co = np.empty(len(me.vertices) * 3, np.float32)
            me.vertices.foreach_get("co", co)
            lv = np.empty(nl, np.int32)
            me.loops.foreach_get("vertex_index", lv)
            ln = np.empty(nl * 3, np.float32)
            me.loops.foreach_get("normal", ln)
            tri = np.empty(ntri * 3, np.int32)
            me.loop_triangles.foreach_get("loops", tri)
            uv = None
            if me.uv_layers.active is not None:
                uv = np.empty(nl * 2, np.float32)
                me.uv_layers.active.data.foreach_get("uv", uv)
        finally:
            ev.to_mesh_clear()
        pos = co.reshape(-1, 3)[lv]
        nrm = ln.reshape(-1, 3)
        cols = [pos, nrm] + ([uv.reshape(-1, 2)] if uv is not None else [])
        corner = np.ascontiguousarray(np.hstack(cols))
        # one vertex per distinct (position, normal, uv): the corners of one
        # smooth surface share theirs
        view = corner.view(np.dtype((np.void, corner.dtype.itemsize * corner.shape[1])))
        _, first, inv = np.unique(view.ravel(), return_index=True, return_inverse=True)
        verts = corner[first]
        idx = inv[tri].astype(np.uint32)
        nvx = len(verts)
        if nvx > mb:
            self.say(o.name, "its mesh needs %d vertices (split at UV seams and sharp edges): over the daemon's %d: "
                     "not sent" % (nvx, mb))
            return None
        p = verts[:, 0:3].astype(np.float64)
        n = verts[:, 3:6].astype(np.float64)
        # Z-up to Y-up (convert.C3): (x, y, z) -> (x, z, -y)
        p3 = np.stack([p[:, 0], p[:, 2], -p[:, 1]], 1).astype(np.float32)
        nn = np.stack([n[:, 0], n[:, 2], -n[:, 1]], 1)
        ln_ = np.linalg.norm(nn, axis=1)
        bad = ln_ < 1e-12
        nn[bad] = (0.0, 1.0, 0.0)
        nn = (nn / np.where(bad, 1.0, ln_)[:, None]).astype(np.float32)
        flags = 0
        arrays = [p3.tobytes(), nn.tobytes()]
        if uv is not None:
            flags |= codec.MESH_UVS
            uvs = verts[:, 6:8].copy()
            uvs[:, 1] = 1.0 - uvs[:, 1]
            arrays.append(uvs.astype(np.float32).tobytes())
        arrays.append(idx.tobytes())
        if not np.all(np.isfinite(p3)):
            self.say(o.name, "its mesh has a NaN or infinite vertex: not sent")
            return None
        size = codec.mesh_put_size(nvx, len(idx), flags)
        if size > maxp:
            self.say(o.name, "its mesh is %d bytes: over the daemon's %d-byte message limit: not sent" % (size, maxp))
            return None
        return codec.mesh_put(cls, flags, nvx, len(idx), arrays)

    # ---- occluders ------------------------------------------------------------------
    def occluder(self, oid, o, depsgraph, target, world=False):
        ev = o.evaluated_get(depsgraph)
        me = ev.to_mesh()
        try:
            me.calc_loop_triangles()
            nt = len(me.loop_triangles)
            lim = min(codec.OCC_MAX_TRIS, self.limits["max_batch"])
            if nt == 0 or nt > lim:
                self.say(o.name, "occluder of %d triangles (1..%d): not sent" % (nt, lim))
                return None
            co = np.empty(len(me.vertices) * 3, np.float32)
            me.vertices.foreach_get("co", co)
            tv = np.empty(nt * 3, np.int32)
            me.loop_triangles.foreach_get("vertices", tv)
        finally:
            ev.to_mesh_clear()
        v = co.reshape(-1, 3).astype(np.float64)[tv]
        h = np.hstack([v, np.ones((len(v), 1))])
        m = np.array(o.matrix_world)
        origin = (0.0, 0.0, 0.0)
        if target is not None:  # OCC_<name>: in <name>'s local space
            m = np.linalg.inv(np.array(target.matrix_world)) @ m
            v = (h @ m.T)[:, :3]
        elif world:
            v = (h @ m.T)[:, :3]
            org = np.array(o.matrix_world.translation)
            v = v - org
            origin = convert.point(tuple(float(x) for x in org))
        yv = np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1).astype(np.float32)
        flags = 0 if world else codec.OCC_ATTACHED
        return codec.occluder_put(oid, flags, origin, yv.tobytes(), nt)

    # ---- materials and textures -------------------------------------------------------
    def material(self, mid, m, img_of, textures):
        base, metallic, rough = tuple(m.diffuse_color), m.metallic, m.roughness
        emissive, strength, alpha = (0.0, 0.0, 0.0), 1.0, base[3]
        tex = [0, 0, 0, 0]
        if m.use_nodes and m.node_tree:
            bsdf = next((n for n in m.node_tree.nodes if n.type == 'BSDF_PRINCIPLED'), None)
            if bsdf is not None:
                inp = bsdf.inputs
                base = tuple(inp["Base Color"].default_value)
                metallic = inp["Metallic"].default_value
                rough = inp["Roughness"].default_value
                alpha = inp["Alpha"].default_value
                em = inp.get("Emission Color") or inp.get("Emission")
                if em is not None:
                    emissive = tuple(em.default_value)[:3]
                es = inp.get("Emission Strength")
                if es is not None:
                    strength = es.default_value
                if inp["Base Color"].is_linked:
                    node = inp["Base Color"].links[0].from_node
                    if node.type == 'TEX_IMAGE' and node.image is not None:
                        tid = img_of.get(node.image.name)
                        got = self.image_bytes(node.image) if tid else None
                        if got is not None:
                            textures[tid] = got
                            tex[0] = tid
                            base = (1.0, 1.0, 1.0, base[3])  # the texture is the colour; glTF's factor 1
                    else:
                        self.say(m.name, "base colour from a %s node: only an Image Texture is mirrored; its "
                                 "default colour is sent" % node.type)
        clamp = lambda x, lo=0.0, hi=1.0: min(max(float(x), lo), hi)
        # glTF's emissive colour is 0..1: a brighter Blender colour keeps its
        # light by moving the excess into the strength (KHR_materials_emissive_strength)
        peak = max(float(c) for c in emissive)
        if peak > 1.0:
            emissive = tuple(float(c) / peak for c in emissive)
            strength *= peak
        flags = 0 if m.use_backface_culling else 1
        alpha_mode = 1 if getattr(m, "blend_method", "OPAQUE") == 'CLIP' else 0
        return codec.material(mid, base_color=tuple(clamp(c) for c in base[:3]) + (clamp(alpha),),
                              metallic=clamp(metallic), roughness=clamp(rough),
                              emissive=tuple(clamp(c) for c in emissive), emissive_strength=clamp(strength, 0, 1e6),
                              flags=flags, alpha_mode=alpha_mode,
                              alpha_cutoff=clamp(getattr(m, "alpha_threshold", 0.5)), textures=tex)

    def image_bytes(self, im, exr=False):
        """(format, flags, bytes) of an image as the daemon takes it: the
        file's own PNG/JPEG (EXR for the sky) bytes, packed or on disk; any
        other image is written to a temporary file in that format"""
        sig = (im.filepath, im.packed_file.size if im.packed_file else -1, tuple(im.size), im.is_dirty, exr)
        c = self.images.get(im.name)
        if c is not None and c[0] == sig:
            return c[1]
        want = ("OPEN_EXR",) if exr else ("PNG", "JPEG")
        fmt = {"PNG": codec.TEX_PNG, "JPEG": codec.TEX_JPEG, "OPEN_EXR": codec.TEX_EXR}
        flags = 0 if exr else codec.TEX_SRGB
        data = None
        if not im.is_dirty and im.file_format in want:
            if im.packed_file:
                data = bytes(im.packed_file.data)
            else:
                path = bpy.path.abspath(im.filepath)
                if path and os.path.isfile(path):
                    with open(path, "rb") as f:
                        data = f.read()
            if data is not None:
                got = (fmt[im.file_format], flags, data)
        if data is None:
            ext = ".exr" if exr else ".png"
            fd, path = tempfile.mkstemp(suffix=ext)
            os.close(fd)
            try:
                cp = im.copy()
                cp.filepath_raw = path
                cp.file_format = "OPEN_EXR" if exr else "PNG"
                cp.save()
                bpy.data.images.remove(cp)
                with open(path, "rb") as f:
                    data = f.read()
            except RuntimeError as e:
                self.say(im.name, "image could not be written as %s: %s" % (ext, e))
                return None
            finally:
                os.unlink(path)
            got = ((codec.TEX_EXR if exr else codec.TEX_PNG), flags, data)
        if len(data) > 64 << 20:
            self.say(im.name, "image is %d bytes: over the protocol's 64 MiB: not sent" % len(data))
            return None
        self.images[im.name] = (sig, got)
        return got

    # ---- lights and the environment ----------------------------------------------------
    def light(self, lid, o):
        L = o.data
        if L.type not in ('POINT', 'SPOT'):
            self.say(o.name, "a %s lamp: Vantage has point and spot lights and one sun: not sent" % L.type.lower())
            return None
        mw = np.array(o.matrix_world)
        pos = convert.point(tuple(float(x) for x in mw[:3, 3]))
        d = -mw[:3, 2]
        nd = np.linalg.norm(d)
        d = convert.point(tuple(float(x) for x in (d / nd if nd > 0 else (0, 0, -1))))
        cd = convert.lamp_candela(L.energy)
        rng = L.cutoff_distance if getattr(L, "use_custom_distance", False) else convert.light_range(cd)
        kind, inner, outer = codec.LIGHT_POINT, 1.0, -1.0
        if L.type == 'SPOT':
            kind = codec.LIGHT_SPOT
            half = L.spot_size / 2.0
            outer = math.cos(half)
            inner = math.cos(half * (1.0 - L.spot_blend))
        col = tuple(max(0.0, float(c)) for c in L.color)
        return codec.pack("light", id=lid, kind=kind, intensity=cd, pos=pos, dir=d, color=col,
                          range=min(max(rng, 1e-3), 1e9), inner_cos=inner, outer_cos=outer)

    def environment(self, scene, sun, img_of, textures):
        env = {}
        if sun is not None:
            mw = np.array(sun.matrix_world)
            z = mw[:3, 2]
            z = z / max(np.linalg.norm(z), 1e-30)
            env["sun_dir"] = convert.point(tuple(float(x) for x in z))
            env["sun_color"] = tuple(min(max(float(c), 0.0), 1.0) for c in sun.data.color)
            env["sun_lux"] = convert.sun_lux(sun.data.energy)
        else:
            env["sun_dir"], env["sun_lux"] = (0.0, 0.0, 0.0), 0.0
        w = scene.world
        if w is None:
            return env
        color, strength, hdri = tuple(w.color), 1.0, None
        if w.use_nodes and w.node_tree:
            bg = next((n for n in w.node_tree.nodes if n.type == 'BACKGROUND'), None)
            if bg is not None:
                color = tuple(bg.inputs["Color"].default_value)[:3]
                strength = bg.inputs["Strength"].default_value
                if bg.inputs["Color"].is_linked:
                    src = bg.inputs["Color"].links[0].from_node
                    if src.type == 'TEX_ENVIRONMENT' and src.image is not None:
                        hdri = src.image
        if hdri is not None:
            tid = img_of.get(hdri.name)
            got = self.image_bytes(hdri, exr=True) if tid else None
            if got is not None:
                textures[tid] = got
                env.update(sky_mode=2, sky_texture=tid, sky_intensity=strength * convert.EFFICACY, sky_rotation=0.0)
                return env
        env.update(sky_mode=0, sky_color=tuple(min(max(float(c), 0.0), 1e6) for c in color[:3]),
                   sky_intensity=min(max(strength * convert.EFFICACY, 0.0), 1e6), sky_texture=0)
        return env

    # ---- selection ------------------------------------------------------------------
    def selected_ids(self, view_layer):
        out = []
        for o in view_layer.objects.selected:
            i = self.obj_ids.get(o.name)
            if i is not None:
                out.append(i)
        return sorted(out)[:codec.SELECT_MAX]
