"""link.py — the add-on's connection to vantaged: one socket in one
background thread, and what the add-on believes the daemon holds. Pure
Python, no bpy: Blender's main thread hands it plain data (`Desired`
snapshots, transforms, a selection) and reads its events; nothing here
touches Blender.

What it owns:
  * connect (TCP or a Unix socket), HELLO with the editor token, and
    reconnect with backoff (0.25 s doubling to 5 s; a refused token stops
    retrying: it will not fix itself);
  * the held model: the entities, lights, materials, textures, meshes,
    occluders, sub-levels and environment of the add-on's own id ranges the
    daemon holds, read back after every (re)connect (ENTITY_LIST,
    LIGHT_LIST, MATERIAL_LIST, MESH_GET, TEXTURE_GET, SUBLEVEL_LIST,
    ENV_GET) and kept up to date as edits are sent;
  * the diff: a full `Desired` snapshot against the held model gives only
    the differences (add what is missing, update what differs, remove what
    Blender no longer has: only ids in the add-on's ranges, so a scene
    shared with other editors is not wiped). Never an ENTITY_ADD of an id
    the daemon holds, so never a duplicate;
  * coalescing and bounds: one pending transform per object (a dict, the
    latest wins), sent as TRANSFORM_SET batches; at most WINDOW requests in
    flight; the events queue for the main thread is a bounded deque. Memory
    is O(objects), whatever the edit rate.

Threading: `offer_*`, `poll_events`, `stats` and `stop` are called from
Blender's main thread; everything else runs on the link's thread. Shared
state is guarded by `self.lock`; the socket is the thread's alone.
"""
import collections
import hashlib
import os
import selectors
import socket
import struct
import threading
import time

from . import codec
from .codec import T

# The add-on's id ranges (README "Editor live-link"): entity and light ids
# 0x424C ("BL") in the top 16 bits; materials and textures 0xB1E00000 +
# n; mesh classes 0xB000 + n. The CLI's imports use 2^63 | ... and the
# daemon's debris 2^62 + n, so none of these collide with them.
ENTITY_PREFIX = 0x424C
MATERIAL_BASE = 0xB1E00000
MATERIAL_SPAN = 0x00100000
CLASS_BASE = 0xB000
CLASS_SPAN = 0x1000
SUBLEVEL_PREFIX = "blender:"

WINDOW = 16          # requests in flight: enough to fill a loopback pipe, small enough to bound memory
BACKOFF_MIN, BACKOFF_MAX = 0.25, 5.0
LIST_PAGE = 1024     # records per ENTITY_LIST page (160 KiB a reply)
IDLE_PING = 10.0     # seconds of quiet before a PING
STALL = 30.0         # seconds without a reply before the connection is made again


def owned_entity(i):
    return (i >> 48) == ENTITY_PREFIX


def owned_material(i):
    return MATERIAL_BASE <= i < MATERIAL_BASE + MATERIAL_SPAN


def owned_class(c):
    return CLASS_BASE <= c < CLASS_BASE + CLASS_SPAN


class Desired:
    """What Blender shows, in protocol terms (built on the main thread by
    scene.py). ents: {id: dict(class_id, sub, flags, material, pos, rot,
    scale)} with `sub` a sub-level name ('' = sub-level 0); meshes:
    {class_id: MESH_PUT payload}; materials: {id: 188-byte record};
    textures: {id: (format, flags, bytes)}; lights: {id: (sub, 80-byte
    record)}; occluders: {id: OCCLUDER_PUT payload}; env: {field: value} to
    lay over the daemon's environment, or None to leave it; excluded:
    sub-level names whose collections are excluded (unloaded)."""

    def __init__(self):
        self.ents, self.meshes, self.materials, self.textures = {}, {}, {}, {}
        self.lights, self.occluders = {}, {}
        self.env = None
        self.excluded = set()


class AuthRefused(Exception):
    pass


class Req:
    """one request of a plan; `wait`: the plan stops until its reply"""
    __slots__ = ("mtype", "payload", "wait", "on_ok", "what", "t0s", "fails", "sent")

    def __init__(self, mtype, payload, wait=False, on_ok=None, what="", t0s=None, fails=None):
        self.mtype, self.payload, self.wait, self.on_ok, self.what, self.t0s = mtype, payload, wait, on_ok, what, t0s
        # [(key, value)] per record: on an ERROR the record `index` names
        # (all of them when it names none) is remembered as refused and not
        # sent again until Blender changes it
        self.fails = fails


def _digest(b):
    return hashlib.blake2b(b, digest_size=16).digest()


class Link:
    def __init__(self, host="127.0.0.1", port=7470, unix="", token="", name="blender", role=codec.ROLE_EDITOR,
                 log=print):
        self.cfg = dict(host=host, port=int(port), unix=unix, token=token, name=name, role=role)
        self.log = log
        self.lock = threading.Lock()
        self.events = collections.deque(maxlen=256)  # (kind, data) for the main thread
        self.full = None             # the latest full Desired not yet diffed
        self.transforms = {}         # id -> (pos, rot, scale, t_handler): one per object
        self.selection = None        # a list of ids to SELECT, or None
        self.state = "disconnected"
        self.last_error = ""
        self.client_id = 0
        self.hello = None
        self.epoch = 0
        self.stall = STALL
        self.has_select = False      # the daemon has SELECT/SELECTED (found at SUBSCRIBE)
        self.skip_selected = False   # the next SELECTED is the one pushed at subscription
        self.latencies = collections.deque(maxlen=8192)  # seconds, handler -> ACK of its epoch
        self.counters = collections.Counter()
        self._stop = threading.Event()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._busy = False
        self._thread = None
        self.sock = None
        self.reset_held()

    # ---- main-thread API -------------------------------------------------------------
    def start(self):
        self._thread = threading.Thread(target=self._run, name="vantage-link", daemon=True)
        self._thread.start()

    def stop(self, timeout=2.0):
        self._stop.set()
        self._wake()
        if self._thread:
            self._thread.join(timeout)
        try:
            self._wake_r.close()
            self._wake_w.close()
        except OSError:
            pass

    def offer_full(self, desired):
        with self.lock:
            self.full = desired
            self.transforms.clear()  # the snapshot holds every transform
        self._wake()

    def offer_transforms(self, trs):
        """trs: {id: (pos, rot, scale, t_handler)}; coalesced per id"""
        with self.lock:
            for i, v in trs.items():
                old = self.transforms.get(i)
                # keep the earliest handler time of a coalesced run (the
                # latency of the first edit the sent value carries)
                self.transforms[i] = v if old is None else (v[0], v[1], v[2], min(old[3], v[3]))
        self._wake()

    def offer_selection(self, id_list):
        with self.lock:
            self.selection = list(id_list)[:codec.SELECT_MAX]
        self._wake()

    def poll_events(self):
        out = []
        with self.lock:
            while self.events:
                out.append(self.events.popleft())
        return out

    def idle(self):
        """True when everything offered has been sent and acknowledged"""
        with self.lock:
            return (self.state == "live" and self.full is None and not self.transforms and self.selection is None
                    and not self._busy)

    def pending(self):
        with self.lock:
            return len(self.transforms)

    # ---- thread side -----------------------------------------------------------------
    def _wake(self):
        try:
            self._wake_w.send(b"x")
        except (BlockingIOError, OSError):
            pass

    def _event(self, kind, data=None):
        with self.lock:
            self.events.append((kind, data))

    def _set_state(self, s, err=None):
        with self.lock:
            self.state = s
            if err is not None:
                self.last_error = err
        self._event("state", (s, err))

    def reset_held(self):
        self.h_ents = {}       # id -> dict as in Desired.ents plus sub_id
        self.h_meshes = {}     # class -> digest of the MESH_PUT payload
        self.h_materials = {}  # id -> 188-byte record
        self.h_textures = {}   # id -> digest of (format, flags, bytes)
        self.h_lights = {}     # id -> (sub_id, 80-byte record)
        self.h_occluders = {}  # id -> digest (no listing in the protocol: unknown after a reconnect)
        self.h_env = None      # the daemon's env record (dict)
        self.h_env_sent = None
        self.sub_ids = {}      # name -> id
        self.h_synced = False  # the last snapshot has been diffed and sent
        self.probed = False    # meshes and textures compared with MESH_GET / TEXTURE_GET this connection
        self.failed = {}       # (kind, id) -> digest of the value the daemon refused: not resent
        self.reread = False

    def _run(self):
        backoff = BACKOFF_MIN
        while not self._stop.is_set():
            try:
                self._set_state("connecting")
                self._connect()
                backoff = BACKOFF_MIN
                self._session()
            except AuthRefused as e:
                self._set_state("refused", str(e))
                return
            except (OSError, codec.ProtocolError, struct.error) as e:
                if self._stop.is_set():
                    break
                self._set_state("disconnected", "%s" % e)
                self.counters["disconnects"] += 1
            finally:
                if self.sock:
                    try:
                        self.sock.close()
                    except OSError:
                        pass
                    self.sock = None
            self._stop.wait(backoff)
            backoff = min(backoff * 2, BACKOFF_MAX)
        self._set_state("disconnected")

    def _connect(self):
        c = self.cfg
        if c["unix"]:
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.settimeout(5)
            s.connect(c["unix"])
        else:
            s = socket.create_connection((c["host"], c["port"]), timeout=5)
            s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        s.settimeout(30)
        self.sock = s
        self.reader = codec.FrameReader(codec.HELLO_MAX_PAYLOAD * 16)
        s.sendall(codec.frame(T["HELLO"], 1, codec.hello(c["role"], c["token"], c["name"])))
        mtype, req, p = self._read_one()
        if mtype == T["ERROR"]:
            code, _, msg = codec.decode_error(p)
            name = codec.ERR_NAMES.get(code, str(code))
            if code == codec.ERR["AUTH"]:
                raise AuthRefused("the daemon refused the token for the %s role (AUTH): %s" %
                                  (("viewer", "commander", "editor")[c["role"]], msg))
            raise AuthRefused("HELLO refused (%s): %s" % (name, msg))
        if mtype != T["HELLO_OK"]:
            raise codec.ProtocolError("expected HELLO_OK, got type 0x%04x" % mtype)
        self.hello = codec.unpack("hello_ok", p)
        self.client_id = self.hello["client_id"]
        self.reader.limit = max(self.hello["max_payload"], 1 << 20) + 64
        if self.hello["role"] != codec.ROLE_EDITOR:
            self._event("log", "connected as %s: this token cannot edit" %
                        ("viewer", "commander", "editor")[self.hello["role"]])

    def _read_one(self):
        while True:
            fr = self.reader.frames()
            if fr:
                # HELLO's answer is the only frame before the session
                return fr[0]
            d = self.sock.recv(65536)
            if not d:
                raise OSError("the daemon closed the connection")
            self.reader.feed(d)

    # ---- the session: plans of requests, a window, pushes --------------------------
    def _session(self):
        self.reset_held()
        self.req = 1
        self.inflight = collections.deque()  # (req, Req)
        self.sock.setblocking(False)
        sel = selectors.DefaultSelector()
        sel.register(self.sock, selectors.EVENT_READ, "sock")
        sel.register(self._wake_r, selectors.EVENT_READ, "wake")
        self.outbuf = bytearray()
        self.last_send = time.monotonic()
        plan = self._plan_connect()
        reply = None
        blocked = False
        self._set_state("syncing")
        try:
            while not self._stop.is_set():
                # advance the plan while the window has room
                while plan is not None and not blocked and len(self.inflight) < WINDOW and len(self.outbuf) < (4 << 20):
                    try:
                        r = plan.send(reply)
                        reply = None
                    except StopIteration:
                        plan = None
                        break
                    self._send(r)
                    if r.wait:
                        blocked = True
                if plan is None:
                    plan = self._next_plan()
                    if plan is not None:
                        reply = None
                        continue
                with self.lock:
                    self._busy = plan is not None or bool(self.inflight) or bool(self.outbuf)
                if not self._busy and self.state == "syncing" and self.h_synced:
                    self._set_state("live")
                events = selectors.EVENT_READ | (selectors.EVENT_WRITE if self.outbuf else 0)
                sel.modify(self.sock, events, "sock")
                # liveness: a PING when the link has been quiet for IDLE_PING
                # seconds, and a connection whose oldest request has had no
                # reply for STALL seconds is dropped and made again (a link
                # that silently stops syncing is the failure to avoid)
                now = time.monotonic()
                if plan is None and not self.inflight and now - self.last_send > IDLE_PING:
                    plan = self._plan_ping()
                    continue
                if self.inflight and now - self.inflight[0][1].sent > self.stall:
                    raise OSError("no reply from the daemon in %g s" % self.stall)
                for key, ev in sel.select(timeout=0.5):
                    if key.data == "wake":
                        try:
                            while self._wake_r.recv(4096):
                                pass
                        except (BlockingIOError, OSError):
                            pass
                        continue
                    if ev & selectors.EVENT_WRITE:
                        n = self.sock.send(self.outbuf)
                        del self.outbuf[:n]
                    if ev & selectors.EVENT_READ:
                        d = self.sock.recv(1 << 20)
                        if not d:
                            raise OSError("the daemon closed the connection")
                        self.reader.feed(d)
                        for mtype, req, p in self.reader.frames():
                            got = self._on_frame(mtype, req, p)
                            if got is not None:
                                blocked, reply = False, got
        finally:
            sel.close()
            with self.lock:
                self._busy = False

    def _send(self, r):
        req = self.req
        self.req = self.req + 1 if self.req < 0xFFFFFFFF else 1
        self.outbuf += codec.frame(r.mtype, req, r.payload)
        r.sent = time.monotonic()
        self.inflight.append((req, r))
        self.last_send = time.monotonic()
        self.counters["sent_" + codec.TYPE_NAME.get(r.mtype, hex(r.mtype))] += 1

    def _on_frame(self, mtype, req, p):
        """a reply to the oldest request in flight, or a pushed frame; returns
        the reply for a waiting plan, else None"""
        if mtype == T["ERROR"] and (req == 0 or not self.inflight):
            # pushed (TIMEOUT before a close): said, and the link made again
            code, _, msg = codec.decode_error(p)
            raise OSError("the daemon sent %s: %s" % (codec.ERR_NAMES.get(code, code), msg))
        if req == 0 and mtype in (T["SELECTED"], T["MARKED"], T["EVENT"]):
            if mtype == T["SELECTED"]:
                s = codec.decode_selected(p)
                if self.skip_selected:
                    self.skip_selected = False
                elif s["client_id"] != self.client_id:
                    self._event("selected", s)
            elif mtype == T["MARKED"]:
                self._event("marked", codec.unpack("marked", p))
            return None
        if not self.inflight:
            raise codec.ProtocolError("a reply (type 0x%04x, req %d) with no request in flight" % (mtype, req))
        rq, r = self.inflight.popleft()
        if rq != req:
            raise codec.ProtocolError("reply for req %d, expected %d" % (req, rq))
        now = time.monotonic()
        if mtype == T["ERROR"]:
            code, index, msg = codec.decode_error(p)
            name = codec.ERR_NAMES.get(code, str(code))
            if r.wait:
                return ("ERROR", code, msg)
            text = "%s refused (%s): %s" % (r.what or codec.TYPE_NAME.get(r.mtype, hex(r.mtype)), name, msg)
            self.counters["errors"] += 1
            self._event("error", text)
            if code == codec.ERR["AUTH"]:
                self._event("log", "this token cannot edit: nothing is mirrored")
            # the held model may now be ahead of the daemon: read it again,
            # and do not resend the value it refused
            if r.fails:
                bad = [r.fails[index]] if index < len(r.fails) else r.fails
                for k, v in bad:
                    self.failed[k] = v
            self.reread = True
            return None
        if r.t0s:
            for t0 in r.t0s:
                self.latencies.append(now - t0)
        if mtype == T["ACK"]:
            a = codec.unpack("ack", p)
            with self.lock:
                self.epoch = a["epoch"]
        if r.on_ok is not None:
            r.on_ok(mtype, p)
        if r.wait:
            return (mtype, p)
        return None

    def _next_plan(self):
        with self.lock:
            # busy from the moment work is taken, so idle() never reads a
            # snapshot taken but not yet sent as done
            self._busy = True
            if self.reread:
                self.reread = False
                return self._plan_read()
            if self.full is not None:
                d, self.full = self.full, None
                self.h_synced = False
                return self._plan_full(d)
            if self.transforms:
                trs, self.transforms = self.transforms, {}
                return self._plan_transforms(trs)
            if self.selection is not None:
                s, self.selection = self.selection, None
                return self._plan_select(s)
        return None

    # ---- plans ---------------------------------------------------------------------
    def _plan_connect(self):
        """once a connection: the subscriptions, then the read-back"""
        # selections (SELECTED) and marks (MARKED) pushed to us; a daemon
        # older than SELECT refuses bit 2 (INVALID): marks alone then
        # (the daemon pushes its current selection right after the ACK, in
        # the same read as the ACK: the flag is set before asking)
        self.skip_selected = True
        r = yield Req(T["SUBSCRIBE"], struct.pack("<I", codec.SUB_MARKS | codec.SUB_SELECTION), wait=True)
        if r[0] == "ERROR":
            self.skip_selected = False
            self.has_select = False
            self._event("log", "this daemon has no SELECT/SELECTED: the selection is not shared")
            yield Req(T["SUBSCRIBE"], struct.pack("<I", codec.SUB_MARKS), wait=True)
        else:
            # the selection pushed at subscription is not applied:
            # connecting never replaces the artist's own selection (which is
            # sent next, as any change)
            self.has_select = True
        yield from self._plan_read()

    def _plan_read(self):
        """read what the daemon holds of the add-on's ranges, then ask the
        main thread for a full snapshot to diff against it"""
        self.h_ents.clear()
        self.h_lights.clear()
        self.h_materials.clear()
        self.h_meshes.clear()
        self.h_textures.clear()
        self.h_occluders.clear()
        self.h_synced = False
        mb = min(self.hello["max_batch"], LIST_PAGE)
        cursor = 0
        while True:
            r = yield Req(T["ENTITY_LIST"], codec.entity_list(cursor, mb), wait=True)
            if r[0] != T["ENTITY_LIST_REPLY"]:
                raise codec.ProtocolError("ENTITY_LIST answered %r" % (r[:3],))
            h, recs = codec.decode_entity_list(r[1])
            for e in recs:
                if owned_entity(e["id"]):
                    self.h_ents[e["id"]] = dict(class_id=e["class_id"], sub_id=e["sublevel"], flags=e["flags"],
                                                material=e["material"], pos=e["pos"], rot=e["rot"],
                                                scale=e["scale"])
            cursor = h["next_cursor"]
            if not cursor:
                break
        lights = yield from self._pages("LIGHT_LIST", "Q", 0, codec.LIGHT_SIZE, "<Q", owned_entity, None)
        self.h_lights.update((i, (None, rec)) for i, rec in lights.items())
        self.h_materials.update((yield from self._pages("MATERIAL_LIST", "I", MATERIAL_BASE - 1, codec.MATERIAL_SIZE,
                                                        "<I", owned_material, MATERIAL_BASE + MATERIAL_SPAN)))
        r = yield Req(T["SUBLEVEL_LIST"], b"", wait=True)
        self.sub_ids = {name: sid for sid, name in codec.decode_sublevel_list(r[1]).items()}
        r = yield Req(T["ENV_GET"], b"", wait=True)
        if r[0] == T["ENV_REPLY"]:
            self.h_env = codec.unpack("env", r[1])
        # meshes and textures are compared when a snapshot names them
        self.probed = False
        self._event("need_full")
        self._set_state("syncing")

    def _pages(self, name, cfmt, cursor, size, ifmt, owned, end):
        """a plan step: every page of LIGHT_LIST or MATERIAL_LIST (cursor
        `cfmt` Q or I, records of `size` bytes whose id is `ifmt`), returning
        {id: record} of the ids `owned` accepts; stops at a cursor >= end"""
        head = struct.Struct("<%sI" % cfmt)
        out = {}
        while True:
            r = yield Req(T[name], head.pack(cursor, min(self.hello["max_batch"], LIST_PAGE)), wait=True)
            if r[0] != T[name + "_REPLY"]:
                raise codec.ProtocolError("%s answered %r" % (name, r[:3]))
            cursor, n = head.unpack_from(r[1])
            for i in range(n):
                rec = bytes(r[1][head.size + size * i:head.size + size * (i + 1)])
                (rid,) = struct.unpack_from(ifmt, rec)
                if owned(rid):
                    out[rid] = rec
            if not cursor or (end is not None and cursor >= end):
                return out

    def _plan_full(self, d):
        # 1. what the daemon holds of the meshes and textures the snapshot
        #    names, once per connection (MESH_GET / TEXTURE_GET), so a
        #    reconnect re-sends only the ones that differ
        if not self.probed:
            self.probed = True
            for c, payload in d.meshes.items():
                r = yield Req(T["MESH_GET"], struct.pack("<H", c), wait=True)
                if r[0] == T["MESH_REPLY"]:
                    self.h_meshes[c] = _digest(r[1])
            for tid, (fmt, flags, data) in d.textures.items():
                want = min(len(data), self.hello["max_payload"] - 16)
                r = yield Req(T["TEXTURE_GET"], struct.pack("<III", tid, 0, want), wait=True)
                if r[0] == T["TEXTURE_REPLY"]:
                    h = codec.unpack("texture_head", r[1])
                    if h["total"] == len(data) and h["total"] <= want:
                        self.h_textures[tid] = _digest(bytes([h["format"], h["flags"]]) + r[1][16:])
        maxp = self.hello["max_payload"]
        mb = self.hello["max_batch"]
        # 2. textures, materials, meshes: the assets the entities name
        for tid, (fmt, flags, data) in d.textures.items():
            dg = _digest(bytes([fmt, flags]) + data)
            if self.h_textures.get(tid) == dg or self.failed.get(("tex", tid)) == dg:
                continue
            chunks = codec.texture_chunks(tid, fmt, flags, data, min(maxp - 16, 1 << 20))
            for k, ch in enumerate(chunks):
                ok = _Ok(self.h_textures, tid, dg) if k == len(chunks) - 1 else None
                yield Req(T["TEXTURE_PUT"], ch, on_ok=ok, what="texture %d" % tid, fails=[(("tex", tid), dg)])
        recs = []
        for mid, rec in d.materials.items():
            if self.h_materials.get(mid) != rec and self.failed.get(("mat", mid)) != rec:
                recs.append((mid, rec))
        for i in range(0, len(recs), 256):
            part = recs[i:i + 256]
            for mid, rec in part:
                self.h_materials[mid] = rec
            yield Req(T["MATERIAL_PUT"], codec.batch([r for _, r in part]), what="materials",
                      fails=[(("mat", mid), rec) for mid, rec in part])
        for c, payload in d.meshes.items():
            dg = _digest(payload)
            if self.h_meshes.get(c) == dg or self.failed.get(("mesh", c)) == dg:
                continue
            if len(payload) > maxp:
                self._event("error", "mesh class %d is %d bytes, over the daemon's %d-byte limit: not sent" %
                            (c, len(payload), maxp))
                self.failed[("mesh", c)] = dg
                continue
            yield Req(T["MESH_PUT"], payload, on_ok=_Ok(self.h_meshes, c, dg), what="mesh class %d" % c,
                      fails=[(("mesh", c), dg)])
        # 3. sub-level names -> ids
        names = sorted({e["sub"] for e in d.ents.values() if e["sub"]} |
                       {s for s, _ in d.lights.values() if s} | set(d.excluded))
        new = [n for n in names if n not in self.sub_ids]
        if new:
            r = yield Req(T["SUBLEVEL_NAMES"], codec.sublevel_names(new), wait=True)
            if r[0] == T["SUBLEVEL_IDS"]:
                for n, sid in zip(new, codec.decode_sublevel_ids(r[1])):
                    self.sub_ids[n] = sid
            else:
                self._event("error", "sub-level names refused: %s" % (r[2],))
        # 4. excluded collections: unload their sub-levels (one epoch each)
        for n in sorted(d.excluded):
            sid = self.sub_ids.get(n)
            if sid is None:
                continue
            held = [i for i, e in self.h_ents.items() if e["sub_id"] == sid]
            if not held and not any(s == sid for s, _ in self.h_lights.values()):
                continue
            r = yield Req(T["SUBLEVEL_UNLOAD"], codec.sublevel_name(n), wait=True)
            if r[0] == T["ACK"] or (r[0] == "ERROR" and r[1] == codec.ERR["STATE"]):
                for i in held:
                    del self.h_ents[i]
                for i in [i for i, (s, _) in self.h_lights.items() if s == sid]:
                    del self.h_lights[i]
                for i in held:
                    self.h_occluders.pop(i, None)
            else:
                self._event("error", "unloading %s refused: %s" % (n, r[2]))
        # 5. entities: removes, then adds (a sub-level that holds nothing
        #    of ours is loaded whole: BEGIN, ADD, LIGHT_PUT, COMMIT), updates,
        #    transforms
        # (an entity's attached occluder goes with it)
        yield from self._removes("ENTITY_REMOVE", "ent", self.h_ents, d.ents, also=self.h_occluders)
        yield from self._removes("LIGHT_REMOVE", "light", self.h_lights, d.lights)
        adds, updates, moves = {}, [], []
        for i, e in d.ents.items():
            if self.failed and self.failed.get(("ent", i)) == _ekey(e):
                continue
            sid = self.sub_ids.get(e["sub"], 0) if e["sub"] else 0
            h = self.h_ents.get(i)
            if h is None:
                adds.setdefault(sid, []).append((i, e))
            elif (h["class_id"], h["sub_id"], h["flags"], h["material"]) != (e["class_id"], sid, e["flags"],
                                                                             e["material"]):
                updates.append((i, e, sid))
            elif not _same_trs(h, e):
                moves.append((i, e))
        held_subs = {h["sub_id"] for h in self.h_ents.values()}
        for sid, items in sorted(adds.items()):
            name = next((n for n, v in self.sub_ids.items() if v == sid), None) if sid else None
            load = bool(sid) and sid not in held_subs and name is not None
            if load:
                r = yield Req(T["SUBLEVEL_BEGIN"], codec.sublevel_name(name, 0), wait=True)
                if r[0] != T["SUBLEVEL_BEGUN"]:
                    # a sub-level still being unloaded (BUSY) is retried on
                    # the next snapshot; anything else is said
                    if r[0] == "ERROR" and r[1] == codec.ERR["BUSY"]:
                        self._event("need_full_later")
                    else:
                        self._event("error", "loading sub-level %s refused: %s" % (name, r[2]))
                    continue
            for k in range(0, len(items), min(mb, 512)):
                part = items[k:k + min(mb, 512)]
                recs = []
                for i, e in part:
                    self.h_ents[i] = _held(e, sid)
                    recs.append(codec.entity(i, e["class_id"], 0 if load else sid, e["flags"], e["material"],
                                             e["pos"], e["rot"], e["scale"]))
                yield Req(T["ENTITY_ADD"], codec.batch(recs), what="adding %d entities" % len(recs),
                          fails=[(("ent", i), _ekey(e)) for i, e in part])
            if load:
                lrecs = [rec for lid, (s, rec) in d.lights.items() if s == name and lid not in self.h_lights]
                for lid, (s, rec) in d.lights.items():
                    if s == name:
                        self.h_lights[lid] = (sid, rec)
                if lrecs:
                    yield Req(T["LIGHT_PUT"], codec.batch(lrecs), what="lights of %s" % name)
                r = yield Req(T["SUBLEVEL_COMMIT"], b"", wait=True)
                if r[0] != T["ACK"]:
                    self._event("error", "committing sub-level %s refused: %s" % (name, r[2]))
                    self.reread = True
        for k in range(0, len(updates), min(mb, 512)):
            part = updates[k:k + min(mb, 512)]
            recs = []
            for i, e, sid in part:
                self.h_ents[i] = _held(e, sid)
                recs.append(codec.entity(i, e["class_id"], sid, e["flags"], e["material"], e["pos"], e["rot"],
                                         e["scale"]))
            yield Req(T["ENTITY_UPDATE"], codec.batch(recs), what="updating %d entities" % len(recs),
                      fails=[(("ent", i), _ekey(e)) for i, e, _ in part])
        yield from self._send_moves([(i, e["pos"], e["rot"], e["scale"], None) for i, e in moves])
        # 6. occluders (attached ones after their entities), lights, env
        for oid, payload in d.occluders.items():
            dg = _digest(payload)
            if self.h_occluders.get(oid) == dg or self.failed.get(("occ", oid)) == dg:
                continue
            yield Req(T["OCCLUDER_PUT"], payload, on_ok=_Ok(self.h_occluders, oid, dg), what="occluder %x" % oid,
                      fails=[(("occ", oid), dg)])
        # (an attached occluder of a removed entity went with it and left
        # h_occluders then; the others Blender no longer has go here)
        yield from self._removes("OCCLUDER_REMOVE", "occ", self.h_occluders, d.occluders)
        lrecs = []
        for lid, (s, rec) in d.lights.items():
            sid = self.sub_ids.get(s, 0) if s else 0
            h = self.h_lights.get(lid)
            if h is not None and h[1] == rec:
                continue
            if self.failed.get(("light", lid)) == rec:
                continue
            self.h_lights[lid] = (sid, rec)
            lrecs.append((lid, rec))
        if lrecs:
            yield Req(T["LIGHT_PUT"], codec.batch([r for _, r in lrecs]), what="%d lights" % len(lrecs),
                      fails=[(("light", lid), rec) for lid, rec in lrecs])
        if d.env is not None and self.h_env is not None:
            env = dict(self.h_env)
            env.update(d.env)
            rec = codec.pack("env", **env)
            if rec != self.h_env_sent and self.failed.get(("env", 0)) != rec:
                self.h_env_sent = rec
                yield Req(T["ENV_SET"], rec, what="environment", fails=[(("env", 0), rec)])
        # 7. materials and textures Blender no longer has (after the
        #    entities stopped using them)
        yield from self._removes("MATERIAL_REMOVE", "mat", self.h_materials, d.materials)
        yield from self._removes("TEXTURE_REMOVE", "tex", self.h_textures, d.textures)
        self.h_synced = True

    def _removes(self, name, kind, held, desired, also=None):
        """a plan step: remove (`name`, batches of max_batch) the ids held and
        no longer desired, but for those whose removal the daemon refused
        before (an entity another connection is loading, a material another
        editor's entity uses): said once, not retried"""
        gone = [i for i in held if i not in desired and ("rm", kind, i) not in self.failed]
        mb = self.hello["max_batch"]
        for k in range(0, len(gone), mb):
            part = gone[k:k + mb]
            for x in part:
                del held[x]
                if also is not None:
                    also.pop(x, None)
            yield Req(T[name], codec.ids(part), what="%s of %d" % (name, len(part)),
                      fails=[(("rm", kind, i), True) for i in part])

    def _send_moves(self, items):
        mb = min(self.hello["max_batch"], 4096)
        for k in range(0, len(items), mb):
            part = items[k:k + mb]
            recs, t0s = [], []
            for i, pos, rot, scale, t0 in part:
                h = self.h_ents[i]
                h["pos"], h["rot"], h["scale"] = pos, rot, scale
                recs.append(codec.transform(i, pos, rot, scale))
                if t0 is not None:
                    t0s.append(t0)
            yield Req(T["TRANSFORM_SET"], codec.batch(recs), what="moving %d entities" % len(recs), t0s=t0s)

    def _plan_transforms(self, trs):
        items = []
        for i, (pos, rot, scale, t0) in trs.items():
            h = self.h_ents.get(i)
            if h is None or not (h["flags"] & codec.ENT_TRANSFORM):
                continue  # not in the daemon yet: the next snapshot adds it
            items.append((i, pos, rot, scale, t0))
        yield from self._send_moves(items)

    def _plan_ping(self):
        yield Req(T["PING"], b"", what="PING")

    def _plan_select(self, s):
        if not self.has_select:
            return
        r = yield Req(T["SELECT"], codec.select(s), wait=True)
        if r[0] == "ERROR":
            if r[1] == codec.ERR["TYPE"]:
                self._event("log", "this daemon has no SELECT: the selection is not shared")
            else:
                self._event("error", "SELECT refused: %s" % r[2])



class _Ok:
    """on success store `value` at table[key] (what the daemon now holds)"""

    def __init__(self, table, key, value):
        self.table, self.key, self.value = table, key, value

    def __call__(self, mtype, p):
        self.table[self.key] = self.value


def _held(e, sid):
    return dict(class_id=e["class_id"], sub_id=sid, flags=e["flags"], material=e["material"], pos=tuple(e["pos"]),
                rot=tuple(e["rot"]), scale=tuple(e["scale"]))


def _ekey(e):
    return (e["class_id"], e["sub"], e["flags"], e["material"], tuple(e["pos"]), tuple(e["rot"]), tuple(e["scale"]))


def _same_trs(h, e):
    """the daemon stores pos as f64 and rot, scale as f32 (scene.py rounds
    them to f32 before they get here); the daemon renormalises rot in double,
    which moves a component by at most ~1 f32 ulp (6e-8): 1e-6 tells that
    apart from any edit a user makes"""
    if tuple(h["pos"]) != tuple(e["pos"]):
        return False
    for a, b in zip(tuple(h["rot"]) + tuple(h["scale"]), tuple(e["rot"]) + tuple(e["scale"])):
        if abs(a - b) > 1e-6 * max(1.0, abs(b)):
            return False
    return True
