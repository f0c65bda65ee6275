"""convert.py — Blender's numbers in Vantage's terms, with no bpy: axes,
transforms, units. The tests check these against Blender's own matrices.

Axes (glTF's convention, which Blender's glTF exporter and Vantage's
importer use): Blender is Z-up, right-handed, -Y forward; Vantage is Y-up,
right-handed. A Blender point (x, y, z) is the Vantage point (x, z, -y):
the rotation C = [[1,0,0],[0,0,1],[0,-1,0]] (det +1, so windings and
handedness are kept). A world matrix M becomes C M C^T; mesh vertices and
normals are mapped by C; UVs get v' = 1 - v (glTF's v runs down the image).

Transforms: Vantage places a mesh by pos + R(rot) (scale ⊙ local). A
Blender world matrix is decomposed in double: scale = the column lengths,
the rotation their directions; a mirror (negative determinant) becomes a
negative x scale, as Vantage's importer does. A matrix with shear (a
non-uniformly scaled parent of a rotated child) has no exact pos/rot/scale:
the nearest is sent: R from the polar decomposition (the rotation closest
to the matrix, SVD), scale = diag(R^T A); `decompose` says how far off
that is (the largest element of A - R diag(scale), relative), so the
caller can log it.

Units: Blender lamps are radiometric (W, W/m^2), Vantage's photometric
(candela, lux, cd/m^2). 683 lm/W (the luminous efficacy at 555 nm, which
Blender's glTF exporter also uses): a point or spot lamp of P watts is
P * 683 / (4 pi) cd; a sun of S W/m^2 is S * 683 lux (capped at the
daemon's 200,000); a world of strength k is a sky of k * 683 cd/m^2. The
ratios between lamps, sun and sky are Blender's, so the daemon's auto
exposure shows what Cycles shows.
"""
import math
import struct

import numpy as np

EFFICACY = 683.0
C3 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
C4 = np.eye(4)
C4[:3, :3] = C3
_F32 = struct.Struct("<f")


def f32(x):
    return _F32.unpack(_F32.pack(x))[0]


def point(p):
    """a Blender point or direction -> Vantage (x, z, -y)"""
    return (p[0], p[2], -p[1])


def matrix_to_y_up(m):
    """a Blender 4x4 world matrix (rows) -> the Vantage one, C M C^T"""
    m = np.asarray(m, dtype=np.float64)
    return C4 @ m @ C4.T


def quat_from_rot(r):
    """a 3x3 rotation (double) -> unit quaternion (x, y, z, w), w >= 0"""
    t = r[0, 0] + r[1, 1] + r[2, 2]
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        w, x, y, z = 0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]) * 2
        w, x, y, z = (r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s
    elif r[1, 1] > r[2, 2]:
        s = math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]) * 2
        w, x, y, z = (r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s
    else:
        s = math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]) * 2
        w, x, y, z = (r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s
    n = math.sqrt(x * x + y * y + z * z + w * w)
    q = (x / n, y / n, z / n, w / n)
    return q if q[3] >= 0 else tuple(-c for c in q)


def decompose(m_blender):
    """a Blender world matrix -> (pos, rot, scale, err, why): pos in f64,
    rot and scale rounded to f32 (what the daemon stores), err the relative
    size of what pos/rot/scale cannot hold (0 for an ordinary matrix; > 0
    with shear), why None or the reason it cannot be sent (two zero scale
    axes, a non-finite number)."""
    m = matrix_to_y_up(m_blender)
    if not np.all(np.isfinite(m)):
        return None, None, None, 0.0, "its world matrix has a NaN or infinite number"
    a = m[:3, :3]
    pos = tuple(float(v) for v in m[:3, 3])
    det = np.linalg.det(a)
    flip = det < 0
    a2 = a @ np.diag([-1.0, 1.0, 1.0]) if flip else a
    s = np.linalg.norm(a2, axis=0)
    if np.count_nonzero(s < 1e-30) >= 2:
        return None, None, None, 0.0, "its scale is 0 on two axes (Vantage allows one)"
    err = 0.0
    if np.any(s < 1e-30):
        # one flat axis: its direction from the other two (the daemon allows one 0 scale)
        k = int(np.argmin(s))
        r = a2 / np.where(s < 1e-30, 1.0, s)
        i, j = [x for x in range(3) if x != k]
        c = np.cross(r[:, (k + 1) % 3], r[:, (k + 2) % 3])
        r[:, k] = c / np.linalg.norm(c)
        s[k] = 0.0
    else:
        r = a2 / s
    if np.max(np.abs(r.T @ r - np.eye(3))) > 1e-9:
        # shear: the nearest rotation (polar decomposition) and the scale that
        # best fits along its axes
        u, _, vt = np.linalg.svd(a2)
        r = u @ vt
        if np.linalg.det(r) < 0:
            u[:, -1] = -u[:, -1]
            r = u @ vt
        s = np.diag(r.T @ a2).copy()
        err = float(np.max(np.abs(a2 - r @ np.diag(s))) / max(1e-30, float(np.max(np.abs(a2)))))
    q = quat_from_rot(r)
    scale = [float(v) for v in s]
    if flip:
        scale[0] = -scale[0]
    return pos, tuple(f32(c) for c in q), tuple(f32(c) for c in scale), err, None


def lamp_candela(watts):
    return watts * EFFICACY / (4.0 * math.pi)


def sun_lux(strength):
    return min(strength * EFFICACY, 200000.0)


def light_range(candela):
    """where the lamp's illuminance falls to 1/20 lux, as the importer's
    rule for a glTF light without a range: I / d^2 = 1/20"""
    return min(max(math.sqrt(20.0 * max(candela, 0.0)), 1e-3), 1e9)


def decompose_many(mats):
    """decompose for n matrices at once (an (n, 4, 4) array of Blender world
    matrices): the same results, vectorised, for a drag of many objects
    (per object numpy calls cost ~0.2 ms; this is ~2 us an object). The rare
    matrix with shear, a zero scale axis or a non-finite number goes through
    `decompose` one by one. Returns a list of (pos, rot, scale, err, why)."""
    m = np.einsum("ij,njk,lk->nil", C4, np.asarray(mats, dtype=np.float64), C4)
    n = len(m)
    a = m[:, :3, :3]
    det = np.linalg.det(a)
    flip = det < 0
    a2 = a.copy()
    a2[flip, :, 0] = -a2[flip, :, 0]
    s = np.linalg.norm(a2, axis=1)  # column lengths, (n, 3)
    ok = np.all(np.isfinite(m.reshape(n, -1)), axis=1) & np.all(s > 1e-30, axis=1)
    r = a2 / np.where(s > 1e-30, s, 1.0)[:, None, :]
    rtr = np.einsum("nji,njk->nik", r, r)
    ok &= np.max(np.abs(rtr - np.eye(3)).reshape(n, -1), axis=1) <= 1e-9
    # quaternions, the four branches of quat_from_rot at once
    t = r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]
    q = np.empty((n, 4))
    c0 = t > 0
    c1 = ~c0 & (r[:, 0, 0] > r[:, 1, 1]) & (r[:, 0, 0] > r[:, 2, 2])
    c2 = ~c0 & ~c1 & (r[:, 1, 1] > r[:, 2, 2])
    c3 = ~c0 & ~c1 & ~c2
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(np.maximum(t + 1.0, 0)) * 2
        q[c0] = np.stack([(r[c0, 2, 1] - r[c0, 1, 2]) / sq[c0], (r[c0, 0, 2] - r[c0, 2, 0]) / sq[c0],
                          (r[c0, 1, 0] - r[c0, 0, 1]) / sq[c0], 0.25 * sq[c0]], 1)
        sq = np.sqrt(np.maximum(1.0 + r[:, 0, 0] - r[:, 1, 1] - r[:, 2, 2], 0)) * 2
        q[c1] = np.stack([0.25 * sq[c1], (r[c1, 0, 1] + r[c1, 1, 0]) / sq[c1], (r[c1, 0, 2] + r[c1, 2, 0]) / sq[c1],
                          (r[c1, 2, 1] - r[c1, 1, 2]) / sq[c1]], 1)
        sq = np.sqrt(np.maximum(1.0 + r[:, 1, 1] - r[:, 0, 0] - r[:, 2, 2], 0)) * 2
        q[c2] = np.stack([(r[c2, 0, 1] + r[c2, 1, 0]) / sq[c2], 0.25 * sq[c2], (r[c2, 1, 2] + r[c2, 2, 1]) / sq[c2],
                          (r[c2, 0, 2] - r[c2, 2, 0]) / sq[c2]], 1)
        sq = np.sqrt(np.maximum(1.0 + r[:, 2, 2] - r[:, 0, 0] - r[:, 1, 1], 0)) * 2
        q[c3] = np.stack([(r[c3, 0, 2] + r[c3, 2, 0]) / sq[c3], (r[c3, 1, 2] + r[c3, 2, 1]) / sq[c3], 0.25 * sq[c3],
                          (r[c3, 1, 0] - r[c3, 0, 1]) / sq[c3]], 1)
    q /= np.linalg.norm(q, axis=1)[:, None]
    q[q[:, 3] < 0] *= -1
    sc = s.copy()
    sc[flip, 0] = -sc[flip, 0]
    q32 = q.astype(np.float32).astype(np.float64).tolist()
    s32 = sc.astype(np.float32).astype(np.float64).tolist()
    pos = m[:, :3, 3].tolist()
    out = []
    for k in range(n):
        if ok[k]:
            out.append((tuple(pos[k]), tuple(q32[k]), tuple(s32[k]), 0.0, None))
        else:
            out.append(decompose(mats[k]))
    return out
