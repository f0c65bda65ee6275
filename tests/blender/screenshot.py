"""screenshot.py — docs/blender_link.png: a small scene built in headless
Blender and mirrored by the live-link into a real vantaged, rendered by
Blender's Cycles on the CPU (left) and by the daemon (`vantage render`,
right) from the same camera: the same eye, target and vertical field of
view (Blender's Z-up camera mapped to Vantage's Y-up as the add-on maps
everything: (x, y, z) -> (x, z, -y)). Both are tone mapped their own way
(Cycles' Filmic, the daemon's ACES with its auto exposure), so the
pictures agree in what is where, not in every shade. The ball is selected
in Blender: the daemon's frame outlines the shared selection (SELECT).

Run: make docs-blender-shot (blender -b --factory-startup --python
tests/blender/screenshot.py -- OUT.png)
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
import harness as H  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Vector  # noqa: E402

import vantage_link as vl  # noqa: E402

W, HT = 640, 360
EYE, AT, FOV = Vector((9.0, -11.0, 5.5)), Vector((0.0, 0.0, 1.0)), 40.0


def mat(name, rgb, metal=0.0, rough=0.5):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = rgb + (1.0,)
    b.inputs["Metallic"].default_value = metal
    b.inputs["Roughness"].default_value = rough
    return m


def add(op, name, loc, m, **kw):
    op(location=loc, **kw)
    o = bpy.context.active_object
    o.name = name
    o.data.materials.append(m)
    return o


def scene():
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    ground = add(bpy.ops.mesh.primitive_plane_add, "Ground", (0, 0, 0.002), mat("Ground", (0.5, 0.5, 0.45), 0, 0.9),
                 size=30)
    red = mat("Red", (0.8, 0.08, 0.05), 0.0, 0.4)
    blue = mat("Blue", (0.05, 0.2, 0.8), 0.0, 0.3)
    gold = mat("Gold", (0.9, 0.65, 0.2), 1.0, 0.25)
    add(bpy.ops.mesh.primitive_cube_add, "Box", (0, 0, 1), red, size=2)
    s = add(bpy.ops.mesh.primitive_uv_sphere_add, "Ball", (3, 1.5, 1), gold, radius=1, segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    c = add(bpy.ops.mesh.primitive_cylinder_add, "Pillar", (-3, 2, 1.5), blue, radius=0.7, depth=3, vertices=40)
    c.rotation_euler.z = 0.3
    t = add(bpy.ops.mesh.primitive_cube_add, "Slab", (1.5, -3, 0.4), blue, size=1)
    t.scale = (2.0, 1.0, 0.4)
    t.rotation_euler.z = 0.5
    sd = bpy.data.lights.new("Sun", 'SUN')
    sd.energy = 4.0
    so = bpy.data.objects.new("Sun", sd)
    so.rotation_euler = (math.radians(40), 0, math.radians(30))
    bpy.context.scene.collection.objects.link(so)
    w = bpy.context.scene.world or bpy.data.worlds.new("World")
    bpy.context.scene.world = w
    w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.35, 0.5, 0.8, 1)
    w.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    return ground


def camera():
    cd = bpy.data.cameras.new("Cam")
    cd.sensor_fit = 'VERTICAL'
    cd.angle_y = math.radians(FOV)
    cam = bpy.data.objects.new("Cam", cd)
    bpy.context.scene.collection.objects.link(cam)
    cam.location = EYE
    cam.rotation_euler = (AT - EYE).to_track_quat('-Z', 'Y').to_euler()
    bpy.context.scene.camera = cam


def cycles(path):
    sc = bpy.context.scene
    sc.render.engine = 'CYCLES'
    sc.cycles.device = 'CPU'
    sc.cycles.samples = 32
    sc.cycles.use_denoising = False
    sc.render.resolution_x, sc.render.resolution_y = W, HT
    sc.render.resolution_percentage = 100
    sc.render.threads_mode = 'FIXED'
    sc.render.threads = 2
    sc.render.filepath = path
    sc.render.image_settings.file_format = 'PNG'
    bpy.ops.render.render(write_still=True)


def load_rgb(path):
    im = bpy.data.images.load(path)
    w, h = im.size
    px = np.array(im.pixels[:], np.float32).reshape(h, w, 4)
    bpy.data.images.remove(im)
    return px


def main():
    out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else os.path.join(H.ROOT, "docs", "blender_link.png")
    tmp = H.tmpdir()
    d = H.Daemon(tmp)
    d.start()
    vl.register()
    scene()
    camera()
    # the artist's selection, shared: the daemon's frame outlines it (cyan)
    for o in bpy.context.view_layer.objects:
        o.select_set(o.name == "Ball")
    m = vl.connect(unix=d.sock, token=H.EDITOR_TOKEN)
    H.check(m.wait_synced(30), "the link did not flush")
    H.check_converged(bpy, d, "screenshot scene")
    left = os.path.join(tmp, "cycles.png")
    right = os.path.join(tmp, "vantage.png")
    cycles(left)
    fmt = lambda v: "%.4f,%.4f,%.4f" % (v[0], v[2], -v[1])  # Blender -> Vantage axes
    rc, so, se = d.cli("render", "--eye", fmt(EYE), "--at", fmt(AT), "--fov", "%g" % FOV, "--size", "%dx%d" % (W, HT),
                       "-o", right, check_rc=False)
    H.check(rc == 0, "vantage render: %s" % se)
    a, b = load_rgb(left), load_rgb(right)
    gap = np.ones((HT, 8, 4), np.float32)
    pic = np.concatenate([a, gap, b], axis=1)
    img = bpy.data.images.new("side_by_side", pic.shape[1], HT, alpha=False)
    img.pixels[:] = pic.ravel()
    img.filepath_raw = out
    img.file_format = 'PNG'
    img.save()
    print("wrote %s (left: Blender Cycles, right: vantaged's frame of the same camera)" % out)
    vl.disconnect()
    H.finish(d, tmp)


H.run(main)
