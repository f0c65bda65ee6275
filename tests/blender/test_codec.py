"""test_codec.py — the add-on's codec (client/blender/vantage_link/codec.py)
against PROTOCOL.md itself: every fixed layout the add-on packs has each
field at the offset and of the size the document's `<!-- layout: NAME -->`
table gives (the tables tests/test_protocol_doc.c checks the C decoder
against), so the Python client cannot drift from the specification. Plain
python3 (no Blender, no numpy): tests/blender/run.sh runs it first.
"""
import os
import re
import struct
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "client", "blender", "vantage_link"))
import codec  # noqa: E402  (the module alone: the package's __init__ needs bpy)

# the add-on's layout -> (the document's layout, offset of the add-on's
# record in it, field renames)
DOC = {
    "hello_ok": ("hello_ok", 0), "ack": ("ack", 0), "entity": ("entity", 0), "transform": ("transform", 0),
    "list_reply": ("list_reply", 0), "mesh_head": ("mesh", 0), "occluder_head": ("occluder", 0),
    "light": ("light", 0), "material_head": ("material", 0), "texref": ("texref", 0),
    "texture_head": ("texture_put", 0), "env": ("env", 0), "sublevel_begun": ("sublevel_begun", 0),
    "selected_head": ("selected_head", 0), "select_head": ("select_head", 0),
}


def doc_layouts(path):
    out, cur = {}, None
    for line in open(path, encoding="utf-8"):
        m = re.match(r"<!-- layout: (\w+)( at \d+)? -->", line.strip())
        if m:
            cur = out.setdefault(m.group(1), {})
            continue
        if cur is None:
            continue
        if not line.startswith("|"):
            if line.strip() == "" and cur:
                cur = None
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 4 or not cells[0].isdigit() or not cells[1].isdigit():
            continue  # a variable-length row (`text_len`, `4 x count`): not a fixed field
        name = cells[3].strip("`")
        if cells[2] != "pad" and name:
            cur[name] = (int(cells[0]), int(cells[1]))
    return out


def field_offsets(lay):
    """{field: (offset, size)} of a codec.Layout, walking its struct format"""
    out, off, names = {}, 0, iter(lay.names)
    fmt = lay.st.format if isinstance(lay.st.format, str) else lay.st.format.decode()
    for num, ch in re.findall(r"(\d*)([a-zA-Z])", fmt[1:]):
        n = int(num) if num else 1
        size = struct.calcsize("<" + ch) * n
        if ch != "x":
            out[next(names)] = (off, size)
        off += size
    return out


def main():
    doc = doc_layouts(os.path.join(ROOT, "protocol", "PROTOCOL.md"))
    fails, checked = [], 0
    for name, (dname, base) in DOC.items():
        if dname not in doc:
            fails.append("PROTOCOL.md has no layout %s" % dname)
            continue
        mine = field_offsets(codec.LAYOUTS[name])
        for field, (off, size) in mine.items():
            want = doc[dname].get(field)
            checked += 1
            if want is None:
                fails.append("%s.%s: not in PROTOCOL.md's %s table" % (name, field, dname))
            elif want != (off + base, size):
                fails.append("%s.%s at %d (%d bytes), PROTOCOL.md says %d (%d bytes)" %
                             (name, field, off + base, size, want[0], want[1]))
    # MARKED: client_id and pad, then the MARK as sent
    mine = field_offsets(codec.LAYOUTS["marked"])
    for field, (off, size) in mine.items():
        want = doc["marked_head"].get(field) if field == "client_id" else \
            (lambda w: (w[0] + 8, w[1]) if w else None)(doc["mark"].get(field))
        checked += 1
        if want != (off, size):
            fails.append("marked.%s at %d, PROTOCOL.md says %s" % (field, off, want))
    # the sizes PROTOCOL.md states for whole records
    for what, got, want in (("entity", codec.ENTITY_SIZE, 160), ("transform", codec.TRANSFORM_SIZE, 64),
                            ("light", codec.LIGHT_SIZE, 80), ("material", codec.MATERIAL_SIZE, 188),
                            ("env", codec.ENV_SIZE, 120), ("hello_ok", codec.LAYOUTS["hello_ok"].size, 28)):
        if got != want:
            fails.append("%s record is %d bytes, PROTOCOL.md says %d" % (what, got, want))
    # a frame cut into 1-byte chunks comes back whole; a non-zero flags is refused
    rd = codec.FrameReader()
    f = codec.frame(codec.T["PING"], 7, b"hello") + codec.frame(codec.T["ACK"], 8, codec.pack("ack", epoch=5, count=1))
    got = []
    for b in f:
        rd.feed(bytes([b]))
        got += rd.frames()
    if [(t, r) for t, r, _ in got] != [(codec.T["PING"], 7), (codec.T["ACK"], 8)] or got[0][2] != b"hello":
        fails.append("FrameReader: %r" % got)
    try:
        rd.feed(struct.pack("<IHHI", 0, 4, 1, 1))
        rd.frames()
        fails.append("FrameReader took a frame with flags 1")
    except codec.ProtocolError:
        pass
    for x in fails:
        print("FAIL:", x)
    print("test_codec: %d fields checked against PROTOCOL.md, %d failures" % (checked, len(fails)))
    return 1 if fails else 0


sys.exit(main())
