"""codec.py — the Vantage wire protocol (protocol/PROTOCOL.md, version 2)
for the Blender add-on: the frame header and the messages the live-link
sends and reads, packed with `struct`. Pure Python, no bpy: the tests and
the bench import it outside Blender too.

What it owns:
  * LAYOUTS: each fixed record described once (a struct format and its
    field names, in PROTOCOL.md's order); `pack(name, **fields)` and
    `unpack(name, buf, off)` are the one encoder and decoder over them;
  * the message type numbers and error codes the add-on uses;
  * FrameReader: cuts a byte stream arriving in any chunking into whole
    frames, refusing a header the stream cannot survive (non-zero flags,
    a length over the negotiated limit);
  * the variable-length payloads (batches, names, meshes, texture chunks).

Numbers are Python ints and floats; u64 ids use all 64 bits. Every f32
and f64 the add-on sends is checked finite by its caller (the daemon
refuses NaN with NONFINITE; the add-on says which object before sending).
"""
import struct

MAGIC = 0x47544E56
VERSION = 2
HEADER = struct.Struct("<IHHI")  # len, type, flags, req
HELLO_MAX_PAYLOAD = 4096

ROLE_VIEWER, ROLE_COMMANDER, ROLE_EDITOR = 0, 1, 2

# message types (PROTOCOL.md "Message types"), the ones the add-on uses
T = dict(
    HELLO=0x0001, HELLO_OK=0x0002, ERROR=0x0003, PING=0x0004, PONG=0x0005,
    SUBSCRIBE=0x0008, EVENT=0x0009, ACK=0x000A,
    ENTITY_ADD=0x0100, ENTITY_ADD_REPLY=0x0101, ENTITY_UPDATE=0x0102, ENTITY_REMOVE=0x0103,
    ENTITY_LIST=0x0104, ENTITY_LIST_REPLY=0x0105, TRANSFORM_SET=0x0107,
    MESH_PUT=0x0110, MESH_GET=0x0111, MESH_REPLY=0x0112,
    OCCLUDER_PUT=0x0120, OCCLUDER_REMOVE=0x0121,
    LIGHT_PUT=0x0130, LIGHT_REMOVE=0x0131, LIGHT_LIST=0x0132, LIGHT_LIST_REPLY=0x0133,
    MATERIAL_PUT=0x0140, MATERIAL_REMOVE=0x0141, MATERIAL_LIST=0x0142, MATERIAL_LIST_REPLY=0x0143,
    TEXTURE_PUT=0x0150, TEXTURE_REMOVE=0x0151, TEXTURE_GET=0x0152, TEXTURE_REPLY=0x0153,
    ENV_SET=0x0160, ENV_GET=0x0161, ENV_REPLY=0x0162,
    SUBLEVEL_NAMES=0x0300, SUBLEVEL_IDS=0x0301, SUBLEVEL_LIST=0x0302, SUBLEVEL_LIST_REPLY=0x0303,
    SUBLEVEL_BEGIN=0x0304, SUBLEVEL_BEGUN=0x0305, SUBLEVEL_COMMIT=0x0306, SUBLEVEL_ABORT=0x0307,
    SUBLEVEL_UNLOAD=0x0308, SUBLEVEL_INFO=0x0309, SUBLEVEL_INFO_REPLY=0x030A,
    MARK=0x0600, MARKED=0x0601, SELECT=0x0602, SELECTED=0x0603,
)
TYPE_NAME = {v: k for k, v in T.items()}

# ERROR codes (PROTOCOL.md "ERROR")
ERR_NAMES = {
    -1: "MAGIC", -2: "VERSION", -3: "TOO_LARGE", -4: "TRUNCATED", -5: "TRAILING", -6: "TYPE",
    -7: "COUNT", -8: "NONFINITE", -9: "INVALID", -10: "STATE", -11: "AUTH", -12: "UNKNOWN_ID",
    -13: "STALE", -14: "DUPLICATE", -15: "LIMIT", -16: "SCENE", -17: "MATRIX", -18: "BUSY",
    -19: "INTERNAL", -20: "UNSUPPORTED", -21: "TIMEOUT", -22: "IO", -23: "NOT_FOUND",
}
ERR = {v: k for k, v in ERR_NAMES.items()}

ENT_DYNAMIC, ENT_TRANSFORM = 0x1, 0x2
MESH_NO_NORMALS, MESH_UVS, MESH_TANGENTS = 0x1, 0x2, 0x4
OCC_ATTACHED = 0x1
TEX_PNG, TEX_JPEG, TEX_EXR = 0, 1, 2
TEX_SRGB = 0x1
SUB_EVENTS, SUB_MARKS, SUB_SELECTION = 0x1, 0x2, 0x4
LIGHT_POINT, LIGHT_SPOT = 0, 1
OCC_MAX_TRIS = 349525  # OCCLUDER_PUT's cost bound (a daemon may be configured lower)
SELECT_MAX = 256

# ---- fixed layouts, each described once ------------------------------------------------
# name: (struct format, field names). A field of n numbers ("3d") is one
# name holding a tuple; "x" pads are written as zero and not named.
_SPEC = {
    "hello_ok": ("<HBxIIIQI", "version role max_payload max_batch max_views epoch client_id"),
    "error": ("<iIH", "code index msg_len"),
    "ack": ("<QI", "epoch count"),
    "entity": ("<QIHHII3d4f3f4x4d6d", "id handle class_id sublevel flags material pos rot scale sphere aabb"),
    "transform": ("<QI3d4f3f", "id handle pos rot scale"),
    "list_reply": ("<QQI", "next_cursor epoch count"),
    "mesh_head": ("<HHII", "class_id flags vertex_count index_count"),
    "occluder_head": ("<QI3dI", "id flags origin tri_count"),
    "light": ("<QB3xf3d3f3ffff4x", "id kind intensity pos dir color range inner_cos outer_cos"),
    "material_head": ("<IIB3xf4fff3fff", "id flags alpha_mode alpha_cutoff base_color metallic roughness "
                      "emissive emissive_strength normal_scale"),
    "texref": ("<IBBBB2f2ffB3x", "texture wrap_s wrap_t min_filter mag_filter offset scale rotation texcoord"),
    "texture_head": ("<IBBxxII", "id format flags total offset"),
    "env": ("<3f3ffBBBx3fffIf4xd3fIf3ffff4x", "sun_dir sun_color sun_lux sky_mode flags exposure_mode sky_color "
            "sky_intensity turbidity sky_texture sky_rotation ground_height ground_color ground_material "
            "fog_density fog_color fog_height_falloff exposure_ev exposure_comp"),
    "sublevel_begun": ("<HH4xQ", "id class_base epoch"),
    "select_head": ("<II", "count flags"),
    "selected_head": ("<IIQ", "client_id count serial"),
    "marked": ("<I4x3dQB3xI", "client_id pos entity kind ttl_ms"),
}


class Layout:
    def __init__(self, name, fmt, names):
        self.name, self.st, self.names = name, struct.Struct(fmt), names.split()
        # how many struct items each named field takes (a "3d" field takes 3)
        widths, i = [], 1
        body = fmt[1:]
        num = ""
        for ch in body:
            if ch.isdigit():
                num += ch
                continue
            n = int(num) if num else 1
            num = ""
            if ch != "x":
                widths.append(n)
        assert len(widths) == len(self.names), name
        self.widths = widths
        self.size = self.st.size

    def pack(self, f):
        vals = []
        for name, w in zip(self.names, self.widths):
            v = f.get(name, 0 if w == 1 else (0,) * w)
            if w == 1:
                vals.append(v)
            else:
                if len(v) != w:
                    raise ValueError("%s.%s needs %d numbers, got %d" % (self.name, name, w, len(v)))
                vals.extend(v)
        return self.st.pack(*vals)

    def unpack(self, buf, off=0):
        vals = self.st.unpack_from(buf, off)
        out, i = {}, 0
        for name, w in zip(self.names, self.widths):
            out[name] = vals[i] if w == 1 else tuple(vals[i:i + w])
            i += w
        return out


LAYOUTS = {k: Layout(k, f, n) for k, (f, n) in _SPEC.items()}
ENTITY_SIZE = LAYOUTS["entity"].size        # 160
TRANSFORM_SIZE = LAYOUTS["transform"].size  # 64
LIGHT_SIZE = LAYOUTS["light"].size          # 80
MATERIAL_SIZE = LAYOUTS["material_head"].size + 4 * LAYOUTS["texref"].size  # 188
ENV_SIZE = LAYOUTS["env"].size              # 120
assert (ENTITY_SIZE, TRANSFORM_SIZE, LIGHT_SIZE, MATERIAL_SIZE, ENV_SIZE) == (160, 64, 80, 188, 120)


def pack(name, **f):
    return LAYOUTS[name].pack(f)


def unpack(name, buf, off=0):
    return LAYOUTS[name].unpack(buf, off)


class ProtocolError(Exception):
    """bytes from the daemon that do not follow PROTOCOL.md (the connection is dropped)"""


# ---- frames ------------------------------------------------------------------------------
def frame(mtype, req, payload=b""):
    return HEADER.pack(len(payload), mtype, 0, req) + payload


class FrameReader:
    """Feed bytes in any chunking; `frames()` yields (type, req, payload) for
    each whole frame. A header with non-zero flags or a length over `limit`
    raises ProtocolError: the stream cannot be trusted past it."""

    def __init__(self, limit=1 << 30):
        self.buf = bytearray()
        self.limit = limit

    def feed(self, data):
        self.buf += data

    def frames(self):
        out = []
        off = 0
        b = self.buf
        while len(b) - off >= HEADER.size:
            ln, mtype, flags, req = HEADER.unpack_from(b, off)
            if flags:
                raise ProtocolError("frame flags 0x%x (must be 0)" % flags)
            if ln > self.limit:
                raise ProtocolError("frame of %d bytes over the limit %d" % (ln, self.limit))
            if len(b) - off - HEADER.size < ln:
                break
            s = off + HEADER.size
            out.append((mtype, req, bytes(b[s:s + ln])))
            off = s + ln
        if off:
            del b[:off]
        return out


# ---- messages ----------------------------------------------------------------------------
def hello(role, token=b"", name=b"blender"):
    if isinstance(token, str):
        token = token.encode()
    if isinstance(name, str):
        name = name.encode()
    if len(token) > 255 or len(name) > 255:
        raise ValueError("token and name are at most 255 bytes")
    return struct.pack("<IHBB", MAGIC, VERSION, role, len(token)) + token + struct.pack("<B", len(name)) + name


def decode_error(p):
    if len(p) < 10:
        return -19, 0xFFFFFFFF, "short ERROR payload"
    e = unpack("error", p)
    msg = p[10:10 + e["msg_len"]].decode("utf-8", "replace")
    return e["code"], e["index"], msg


def batch(records):
    """count u32, then the records (ENTITY_ADD/UPDATE, TRANSFORM_SET, LIGHT_PUT, MATERIAL_PUT)"""
    return struct.pack("<I", len(records)) + b"".join(records)


def ids(values):
    """count u32, then u64 ids (the REMOVE messages, ENTITY_GET)"""
    return struct.pack("<I%dQ" % len(values), len(values), *values)


def entity(id, class_id=0, sublevel=0, flags=0, material=0, pos=(0, 0, 0), rot=(0, 0, 0, 1), scale=(1, 1, 1),
           handle=0):
    return pack("entity", id=id, handle=handle, class_id=class_id, sublevel=sublevel, flags=flags, material=material,
                pos=pos, rot=rot, scale=scale)


def transform(id, pos, rot, scale, handle=0):
    return pack("transform", id=id, handle=handle, pos=pos, rot=rot, scale=scale)


def entity_list(cursor, maxn):
    return struct.pack("<QI", cursor, maxn)


def decode_entity_list(p):
    h = unpack("list_reply", p)
    n = h["count"]
    if len(p) != 20 + ENTITY_SIZE * n:
        raise ProtocolError("ENTITY_LIST_REPLY of %d bytes for %d records" % (len(p), n))
    return h, [unpack("entity", p, 20 + ENTITY_SIZE * i) for i in range(n)]


def mesh_put(class_id, flags, vertex_count, index_count, arrays):
    """arrays: the bytes of positions, normals, uvs, tangents, indices in
    PROTOCOL.md's order, those the flags leave out absent"""
    return pack("mesh_head", class_id=class_id, flags=flags, vertex_count=vertex_count,
                index_count=index_count) + b"".join(arrays)


def mesh_put_size(vertex_count, index_count, flags):
    per = 12 + (0 if flags & MESH_NO_NORMALS else 12) + (8 if flags & MESH_UVS else 0) + \
        (16 if flags & MESH_TANGENTS else 0)
    return 12 + per * vertex_count + 4 * index_count


def occluder_put(id, flags, origin, tris_bytes, tri_count):
    return pack("occluder_head", id=id, flags=flags, origin=origin, tri_count=tri_count) + tris_bytes


def material(id, base_color=(1, 1, 1, 1), metallic=0.0, roughness=1.0, emissive=(0, 0, 0), emissive_strength=1.0,
             flags=0, alpha_mode=0, alpha_cutoff=0.5, normal_scale=1.0, textures=(0, 0, 0, 0)):
    """one 188-byte material record; textures: ids for base colour,
    metallic-roughness, normal and emissive (0 = none), each sampled with
    repeat wrapping and trilinear filtering, identity transform"""
    head = pack("material_head", id=id, flags=flags, alpha_mode=alpha_mode, alpha_cutoff=alpha_cutoff,
                base_color=base_color, metallic=metallic, roughness=roughness, emissive=emissive,
                emissive_strength=emissive_strength, normal_scale=normal_scale)
    refs = b"".join(pack("texref", texture=t, wrap_s=0, wrap_t=0, min_filter=5, mag_filter=1, offset=(0, 0),
                         scale=(1, 1), rotation=0, texcoord=0) for t in textures)
    return head + refs


def decode_material(p, off=0):
    m = unpack("material_head", p, off)
    m["textures"] = tuple(unpack("texref", p, off + 60 + 32 * i)["texture"] for i in range(4))
    return m


def texture_chunks(id, fmt, flags, data, max_chunk):
    """TEXTURE_PUT payloads of at most max_chunk image bytes each"""
    total = len(data)
    out = []
    for off in range(0, total, max_chunk):
        out.append(pack("texture_head", id=id, format=fmt, flags=flags, total=total, offset=off) +
                   data[off:off + max_chunk])
    return out


def sublevel_names(names):
    out = [struct.pack("<I", len(names))]
    for n in names:
        b = n.encode("utf-8")
        if not 1 <= len(b) <= 255:
            raise ValueError("sub-level name %r is %d bytes (1..255)" % (n, len(b)))
        out.append(struct.pack("<B", len(b)) + b)
    return b"".join(out)


def decode_sublevel_ids(p):
    (n,) = struct.unpack_from("<I", p)
    if len(p) != 4 + 2 * n:
        raise ProtocolError("SUBLEVEL_IDS of %d bytes for %d ids" % (len(p), n))
    return list(struct.unpack_from("<%dH" % n, p, 4))


def sublevel_name(name, classes=None):
    """SUBLEVEL_UNLOAD's payload, or SUBLEVEL_BEGIN's with classes"""
    b = name.encode("utf-8")
    head = b"" if classes is None else struct.pack("<H", classes)
    return head + struct.pack("<B", len(b)) + b


def decode_sublevel_list(p):
    """{id: name}"""
    (n,) = struct.unpack_from("<I", p)
    off, out = 4, {}
    for _ in range(n):
        sid, ln = struct.unpack_from("<HB", p, off)
        out[sid] = p[off + 3:off + 3 + ln].decode("utf-8", "replace")
        off += 3 + ln
    return out


def select(id_list):
    if len(id_list) > SELECT_MAX:
        raise ValueError("SELECT carries at most %d ids" % SELECT_MAX)
    return pack("select_head", count=len(id_list), flags=0) + struct.pack("<%dQ" % len(id_list), *id_list)


def decode_selected(p):
    h = unpack("selected_head", p)
    n = h["count"]
    if len(p) != 16 + 8 * n:
        raise ProtocolError("SELECTED of %d bytes for %d ids" % (len(p), n))
    h["ids"] = list(struct.unpack_from("<%dQ" % n, p, 16))
    return h
