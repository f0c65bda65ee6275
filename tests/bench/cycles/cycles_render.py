"""cycles_render.py — Blender (3.4) side of the Cycles comparison: imports a
GLB written by `vantage export`, sets up the camera, sun, sky and ground the
daemon drew with, renders with Cycles on the CPU and writes linear float
arrays (.npy, rows top-down, RGB) for compare.py: cycles.npy, plus the
daemon's own EXR (vantage.npy) and PNG (vantage_png.npy, sRGB codes / 255)
decoded by Blender's image readers, so compare.py needs numpy alone.

Run: blender -b --factory-startup --python cycles_render.py -- OPTIONS

Units. The daemon's scene is photometric: the sun's illuminance in lux,
the sky's radiance in cd/m^2, and its frame is radiance x the exposure
scale s = 1 / (1.2 x 2^EV100) (render/vt_scene.h). Cycles is unit-free
and linear: a sun of strength E gives a white Lambertian surface facing it
the radiance E / pi, as lux gives nits. So Blender's sun strength is set to
lux x s, the world's radiance to nits x s, and Cycles' film then holds the
daemon's exposed radiance directly (no 683 lm/W: that constant would cancel
in the exposure anyway). The view transform is 'Standard' with exposure 0
and gamma 1, and the output is a float EXR, so no display transform touches
the numbers; compare.py tone maps both with the daemon's ACES curve.

Coordinates: glTF is Y-up, Blender Z-up; the glTF importer maps (x, y, z)
to (x, -z, y), and so do the camera, sun and sky directions set here.

The analytic sky: the daemon's Preetham sky (render/vt_scene.c,
vt_sky_radiance) is evaluated here in numpy, formula for formula, into an
equirectangular float image used as Blender's environment texture, so both
renderers light with the same sky radiance; a uniform sky is the same
colour as the world background.

Emission (emissive x KHR_materials_emissive_strength, cd/m^2 in the
daemon) is scaled by s as well.

The ground: the daemon's infinite plane y = H with albedo A is a 40 km
square at z = H with a Principled BSDF of base colour A, roughness 1,
specular 0.5 (F0 0.04). The imported point and spot lights are removed
(the daemon's lamps are in their own units and, by day at EV100 15, below
a 0.5 % of the sun's contribution; they would need a separate conversion).
"""
import math
import os
import sys

import numpy
numpy.bool = bool  # Debian's numpy 1.24 lacks numpy.bool, which Blender 3.4's glTF importer uses
import numpy as np  # noqa: E402

import bpy  # noqa: E402
from mathutils import Matrix, Vector  # noqa: E402


def args():
    a = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    o = {"up": "0,1,0", "fov": "60", "near": "0.1", "far": "10000", "size": "480x270", "samples": "64",
         "ground": "", "threads": "2", "denoise": "0", "sun-color": "1,1,1", "sun": "", "vantage-exr": "",
         "vantage-png": "", "seed": "1", "name": "cycles"}
    i = 0
    while i < len(a):
        if not a[i].startswith("--") or i + 1 >= len(a):
            sys.exit("cycles_render.py: bad argument %s" % a[i])
        o[a[i][2:]] = a[i + 1]
        i += 2
    for k in ("glb", "eye", "at", "sky", "ev", "out"):
        if k not in o:
            sys.exit("cycles_render.py: --%s is required" % k)
    return o


def vec(s):
    return [float(x) for x in s.split(",")]


def to_blender(v):
    """a glTF (Y-up) direction or point to Blender's Z-up frame, as the importer maps it"""
    return Vector((v[0], -v[2], v[1]))


def sun_dir(az_deg, el_deg):
    """the CLI's convention (cli_env.c): azimuth from +Z towards +X, elevation up; towards the sun"""
    az, el = math.radians(az_deg), math.radians(el_deg)
    return [math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)]


# ---- the daemon's Preetham sky (render/vt_scene.c), vectorized ------------------------------
K = [[(0.1787, -1.4630), (-0.3554, 0.4275), (-0.0227, 5.3251), (0.1206, -2.5771), (-0.0670, 0.3703)],
     [(-0.0193, -0.2592), (-0.0665, 0.0008), (-0.0004, 0.2125), (-0.0641, -0.8989), (-0.0033, 0.0452)],
     [(-0.0167, -0.2608), (-0.0950, 0.0092), (-0.0079, 0.2102), (-0.0441, -1.6537), (-0.0109, 0.0529)]]


def perez(c, cos_theta, gamma):
    cg = np.cos(gamma)
    return (1 + c[0] * np.exp(c[1] / cos_theta)) * (1 + c[2] * np.exp(c[3] * gamma) + c[4] * cg * cg)


def preetham(d, sdir, T):
    """d: (..., 3) unit directions, Y-up; radiance RGB in cd/m^2 (sky multiplier 1)"""
    perez_c = [[k[i][0] * T + k[i][1] for i in range(5)] for k in K]
    th = min(math.acos(max(-1.0, min(1.0, sdir[1]))), 1.5)
    t2, t3 = th * th, th * th * th
    chi = (4.0 / 9.0 - T / 120.0) * (math.pi - 2 * th)
    zen = [((4.0453 * T - 4.9710) * math.tan(chi) - 0.2155 * T + 2.4192) * 1000.0,
           T * T * (0.00166 * t3 - 0.00375 * t2 + 0.00209 * th) + T * (-0.02903 * t3 + 0.06377 * t2 - 0.03202 * th + 0.00394)
           + (0.11693 * t3 - 0.21196 * t2 + 0.06052 * th + 0.25886),
           T * T * (0.00275 * t3 - 0.00610 * t2 + 0.00317 * th) + T * (-0.04214 * t3 + 0.08970 * t2 - 0.04153 * th + 0.00516)
           + (0.15346 * t3 - 0.26756 * t2 + 0.06670 * th + 0.26688)]
    inv_f0 = [1.0 / perez(perez_c[c], 1.0, th) for c in range(3)]
    dy = np.maximum(d[..., 1], 0.01)
    cg = d[..., 0] * sdir[0] + dy * sdir[1] + d[..., 2] * sdir[2]
    gamma = np.arccos(np.clip(cg, -1, 1))
    Y = zen[0] * perez(perez_c[0], dy, gamma) * inv_f0[0]
    x = zen[1] * perez(perez_c[1], dy, gamma) * inv_f0[1]
    y = zen[2] * perez(perez_c[2], dy, gamma) * inv_f0[2]
    ok = (y > 1e-4) & (Y > 0)
    ys = np.where(ok, y, 1.0)
    X, Z = x / ys * Y, (1 - x - y) / ys * Y
    sy = sdir[1]
    fade = 1.0 if sy >= 0 else 0.001 if sy <= -0.1 else 0.001 + 0.999 * (1 + sy * 10)
    rgb = np.stack([3.2406 * X - 1.5372 * Y - 0.4986 * Z, -0.9689 * X + 1.8758 * Y + 0.0415 * Z,
                    0.0557 * X - 0.2040 * Y + 1.0570 * Z], -1)
    return np.where(ok[..., None], np.maximum(rgb, 0), 0) * fade


def sky_image(sdir, T, mul, scale, path, w=1024, h=512):
    """Blender's equirectangular layout (Cycles' direction_to_equirectangular):
    u = 0.5 - atan2(dir.y, dir.x) / 2pi, v = 0.5 + asin(dir.z) / pi (Z-up),
    rows bottom-up"""
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    phi = (u - 0.5) * 2 * math.pi
    lat = (v - 0.5) * math.pi
    lat, phi = np.meshgrid(lat, phi, indexing="ij")
    bx, by, bz = np.cos(lat) * np.cos(phi), -np.cos(lat) * np.sin(phi), np.sin(lat)
    d = np.stack([bx, bz, -by], -1)  # Blender (x, y, z) -> glTF (x, z, -y)
    rgb = preetham(d, sdir, T) * np.array(mul) * scale
    img = bpy.data.images.new("vantage_sky", w, h, alpha=False, float_buffer=True)
    # Non-Color before the pixels: a 'Linear' generated image is written to
    # EXR sRGB-encoded by Blender 3.4 (0.4 comes back 0.665)
    img.colorspace_settings.name = "Non-Color"
    px = np.concatenate([rgb, np.ones((h, w, 1))], -1).astype(np.float32)
    img.pixels.foreach_set(px.ravel())
    # Cycles reads a generated image's original buffer, not edited pixels:
    # written to a float EXR and loaded back, the sky is a file like any other
    img.filepath_raw = path
    img.file_format = "OPEN_EXR"
    img.save()
    bpy.data.images.remove(img)
    img = bpy.data.images.load(path)
    img.colorspace_settings.name = "Non-Color"
    return img


def world(o, scale, sdir):
    w = bpy.data.worlds.new("vantage_world")
    bpy.context.scene.world = w
    w.use_nodes = True
    nt = w.node_tree
    bg = nt.nodes["Background"]
    bg.inputs["Strength"].default_value = 1.0
    kind, _, rest = o["sky"].partition(":")
    if kind == "color":
        c = [x * scale for x in vec(rest)]
        bg.inputs["Color"].default_value = (c[0], c[1], c[2], 1.0)
    elif kind == "analytic":
        p = vec(rest)  # turbidity[,R,G,B multiplier]
        mul = p[1:4] if len(p) >= 4 else [1, 1, 1]
        env = nt.nodes.new("ShaderNodeTexEnvironment")
        env.image = sky_image(sdir, p[0], mul, scale, os.path.join(o["out"], "sky.exr"))
        env.interpolation = "Linear"
        nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    else:
        sys.exit("cycles_render.py: --sky color:R,G,B or analytic:T[,R,G,B]")


def ground(o):
    if not o["ground"]:
        return
    h, r, g, b = vec(o["ground"])
    bpy.ops.mesh.primitive_plane_add(size=40000.0, location=(0, 0, h))
    pl = bpy.context.active_object
    m = bpy.data.materials.new("vantage_ground")
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (r, g, b, 1)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular"].default_value = 0.5
    pl.data.materials.append(m)


def camera(o):
    eye, at, up = to_blender(vec(o["eye"])), to_blender(vec(o["at"])), to_blender(vec(o["up"]))
    f = (at - eye).normalized()
    r = f.cross(up).normalized()
    u = r.cross(f)
    rot = Matrix((r, u, -f)).transposed()  # the camera looks down its -Z, +Y up
    cd = bpy.data.cameras.new("vantage_camera")
    cd.sensor_fit = "VERTICAL"
    cd.angle_y = math.radians(float(o["fov"]))
    cd.clip_start, cd.clip_end = float(o["near"]), float(o["far"])
    cam = bpy.data.objects.new("vantage_camera", cd)
    cam.matrix_world = Matrix.Translation(eye) @ rot.to_4x4()
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam


def sun(o, scale):
    if not o["sun"]:
        return None
    az, el, lux = vec(o["sun"])
    d = sun_dir(az, el)
    ld = bpy.data.lights.new("vantage_sun", "SUN")
    ld.energy = lux * scale
    ld.color = vec(o["sun-color"])
    ld.angle = math.radians(0.53)  # the real sun's disc; the daemon's is a point, this only softens edges by cm
    ob = bpy.data.objects.new("vantage_sun", ld)
    ob.rotation_mode = "QUATERNION"
    ob.rotation_quaternion = to_blender(d).to_track_quat("Z", "Y")  # the light shines along its -Z
    bpy.context.scene.collection.objects.link(ob)
    return d


def emission(scale):
    """the materials' emission is radiance in cd/m^2 in the daemon (emissive
    x strength): scaled by the exposure like the sun and sky"""
    for m in bpy.data.materials:
        if not m.use_nodes:
            continue
        for n in m.node_tree.nodes:
            if n.type == "BSDF_PRINCIPLED":
                n.inputs["Emission Strength"].default_value *= scale
            elif n.type == "EMISSION":
                n.inputs["Strength"].default_value *= scale


def load_pixels(path, colorspace):
    img = bpy.data.images.load(path)
    img.colorspace_settings.name = colorspace
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[::-1, :, :3].copy()  # Blender's rows are bottom-up


def main():
    o = args()
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    bpy.ops.import_scene.gltf(filepath=o["glb"])
    for ob in list(bpy.data.objects):  # the exported sun and lamps: replaced / left out (see the header)
        if ob.type == "LIGHT":
            bpy.data.objects.remove(ob, do_unlink=True)
    scale = 1.0 / (1.2 * 2.0 ** float(o["ev"]))
    emission(scale)
    os.makedirs(o["out"], exist_ok=True)
    d = sun(o, scale)
    world(o, scale, d if d else [0, 1, 0])
    ground(o)
    camera(o)
    sc = bpy.context.scene
    w, h = (int(x) for x in o["size"].split("x"))
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = int(o["samples"])
    sc.cycles.use_adaptive_sampling = False
    # Debian's Blender 3.4 is built without OpenImageDenoise (and OptiX needs
    # a GPU): no denoiser, so the noise is compare.py's ceiling (two seeds)
    have_oidn = "OPENIMAGEDENOISE" in [e.identifier for e in sc.cycles.bl_rna.properties["denoiser"].enum_items]
    sc.cycles.use_denoising = o["denoise"] == "1" and have_oidn
    if sc.cycles.use_denoising:
        sc.cycles.denoiser = "OPENIMAGEDENOISE"
    sc.cycles.seed = int(o["seed"])
    sc.render.threads_mode = "FIXED"
    sc.render.threads = int(o["threads"])
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = w, h, 100
    sc.render.film_transparent = False
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.color_mode = "RGB"
    out = o["out"]
    os.makedirs(out, exist_ok=True)
    exr = os.path.join(out, o["name"] + ".exr")
    sc.render.filepath = exr
    bpy.ops.render.render(write_still=True)
    np.save(os.path.join(out, o["name"] + ".npy"), load_pixels(exr, "Non-Color"))
    if o["vantage-exr"]:
        np.save(os.path.join(out, "vantage.npy"), load_pixels(o["vantage-exr"], "Non-Color"))
    if o["vantage-png"]:
        np.save(os.path.join(out, "vantage_png.npy"), load_pixels(o["vantage-png"], "Non-Color"))
    print("cycles_render.py: %s: %dx%d, %d samples, seed %s, denoiser %s" % (
        exr, w, h, sc.cycles.samples, o["seed"], "OpenImageDenoise" if sc.cycles.use_denoising else "none"))


main()
