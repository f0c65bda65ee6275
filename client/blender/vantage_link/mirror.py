"""mirror.py — Blender's edits to the link: depsgraph and undo handlers
mark what changed (dirty sets), a timer on the main thread flushes them at
up to 60 Hz (transforms as one pending value per object; anything
structural as a full snapshot the link diffs), and the link's events
(status, errors, other clients' selections) come back to the UI here.

Load: a handler call costs O(updates in it) (a name and a time into a
dict); a flush of k moved objects O(k) matrix decompositions; a full
snapshot O(objects) plus the meshes that changed. A drag of 1,000 objects
is 1,000 dict entries, whatever the frame rate.

Timers do not run while a background (`blender -b --python`) script runs:
scripts and tests call `tick()` (or `wait_synced`) themselves.
"""
import time

import bpy

from . import codec, link as lk, scene as sc

TICK = 1.0 / 60.0          # flush period: at most 60 Hz
FULL_MIN_INTERVAL = 0.1    # seconds between full snapshots (an edit storm gives 10 a second)
SELECT_DEBOUNCE = 0.05     # a selection stable this long is sent
LOG_LINES = 50


class Mirror:
    def __init__(self, host, port, unix, token, role=codec.ROLE_EDITOR, name="blender"):
        self.log_lines = []
        self.status = "connecting"
        self.last_error = ""
        self.link = lk.Link(host=host, port=port, unix=unix, token=token, name=name, role=role, log=self._log_thread)
        self.builder = sc.Builder(self.log, dict(max_payload=16 << 20, max_batch=65536))
        self.dirty_xf = {}         # object name -> time of the first handler call that moved it
        self.structural = True     # a full snapshot is due
        self.need_full = False     # the link asked for one (after a (re)connect)
        self.full_later = 0.0
        self.last_full = 0.0
        self.sig = None
        self.sel_sent = None
        self.sel_seen = (None, 0.0)
        self.applying_selection = False
        self.remote_selection = None  # the last SELECTED from another client: (client_id, ids)
        self.marks = []
        self.running = False

    # ---- logging: the panel's last lines and Blender's console ---------------------
    def log(self, msg, error=False):
        line = ("error: " if error else "") + msg
        print("vantage:", line)
        self.log_lines.append(line)
        del self.log_lines[:-LOG_LINES]
        if error:
            self.last_error = msg

    def _log_thread(self, msg):
        # from the link's thread: through its event queue, not the UI
        self.link._event("log", msg)

    # ---- life ----------------------------------------------------------------------
    def start(self):
        global _active
        _active = self
        self.running = True
        self.link.start()
        for h, f in _handlers():
            if f not in h:
                h.append(f)
        if not bpy.app.background and not bpy.app.timers.is_registered(_timer):
            bpy.app.timers.register(_timer, first_interval=TICK, persistent=True)

    def stop(self):
        global _active
        if _active is self:
            _active = None
            for h, f in _handlers():
                if f in h:
                    h.remove(f)
            if bpy.app.timers.is_registered(_timer):
                bpy.app.timers.unregister(_timer)
        self.running = False
        self.link.stop()
        self.status = "disconnected"

    # ---- handlers (main thread) ------------------------------------------------------
    def on_depsgraph(self, scene, depsgraph):
        if self.applying_selection:
            return
        t = time.monotonic()
        for u in depsgraph.updates:
            idb = u.id.original if u.id is not None else None
            if isinstance(idb, bpy.types.Object):
                if u.is_updated_transform:
                    self.dirty_xf.setdefault(idb.name, t)
                if u.is_updated_geometry:
                    self.builder.mesh_dirty.add(("obj", idb.name))
                    if idb.type == 'MESH' and idb.data is not None:
                        self.builder.mesh_dirty.add(("mesh", idb.data.name))
                    self.structural = True
                if u.is_updated_shading:
                    self.structural = True
            elif isinstance(idb, bpy.types.Mesh):
                self.builder.mesh_dirty.add(("mesh", idb.name))
                self.structural = True
            elif isinstance(idb, (bpy.types.Material, bpy.types.Image, bpy.types.Light, bpy.types.World,
                                  bpy.types.Collection, bpy.types.NodeTree)):
                self.structural = True
        # additions, deletions, exclusions show as a changed signature
        vl = bpy.context.view_layer
        sig = (len(scene.objects), len(vl.objects), _exclusions(vl.layer_collection), scene.world)
        if sig != self.sig:
            self.sig = sig
            self.structural = True

    def on_undo(self, *args):
        # undo/redo: the main database was reloaded; a diff against the
        # daemon's state puts back exactly what changed
        self.structural = True
        for v in self.builder.meshes.values():
            self.builder.mesh_dirty.add(v[1])
        self.sig = None

    # ---- the flush ------------------------------------------------------------------
    def tick(self):
        now = time.monotonic()
        for kind, data in self.link.poll_events():
            if kind == "state":
                s, err = data
                self.status = s
                _redraw()
                if s == "refused":
                    self.log(err, error=True)
                elif err and s == "disconnected":
                    self.log("disconnected: %s (reconnecting)" % err)
                elif s == "live":
                    self.log("live: the daemon mirrors this scene")
                if s == "connecting" or s == "syncing":
                    h = self.link.hello
                    if h:
                        self.builder.limits = dict(max_payload=h["max_payload"], max_batch=h["max_batch"])
            elif kind == "need_full":
                self.need_full = True
                self.sel_sent = None
            elif kind == "need_full_later":
                self.full_later = now + 0.2
            elif kind == "error":
                self.log(data, error=True)
            elif kind == "log":
                self.log(data)
            elif kind == "selected":
                self.apply_selection(data)
            elif kind == "marked":
                self.marks.append(data)
                del self.marks[:-16]
                # a commander's select is a MARK of kind 1 naming an entity
                # (vantage commander, the browser's): shown as Blender's
                # selection when the entity is one of ours
                if data["kind"] == 1 and data["entity"] in self.builder.names and \
                        data["client_id"] != self.link.client_id:
                    self.apply_selection(dict(client_id=data["client_id"], ids=[data["entity"]]))
        if self.status not in ("syncing", "live"):
            return
        if self.full_later and now >= self.full_later:
            self.full_later = 0.0
            self.structural = True
        if self.builder.mesh_retry and now >= self.builder.mesh_retry:
            self.builder.mesh_retry = 0.0
            self.structural = True
        if (self.need_full or self.structural) and now - self.last_full >= FULL_MIN_INTERVAL:
            ctx = bpy.context
            dg = ctx.evaluated_depsgraph_get()
            d = self.builder.build(ctx.scene, ctx.view_layer, dg)
            self.link.offer_full(d)
            self.need_full = self.structural = False
            self.dirty_xf.clear()
            self.last_full = now
        elif self.dirty_xf and not self.need_full and not self.structural:
            self.flush_transforms()
        self.share_selection(now)

    def flush_transforms(self):
        todo = dict(self.dirty_xf)
        self.dirty_xf.clear()
        # one pass over the objects: names (bpy.data.objects.get is a linear
        # search) and parents (Object.children is a scan of its own)
        by_name, kids = {}, {}
        for k, o in enumerate(bpy.data.objects):
            by_name[o.name] = (o, k)
            if o.parent is not None:
                kids.setdefault(o.parent.name, []).append(o.name)
        # a moved parent moves its children: their world matrices changed too
        stack = [n for n in todo if n in kids]
        while stack:
            p = stack.pop()
            for c in kids.get(p, ()):
                if c not in todo:
                    todo[c] = todo[p]
                    stack.append(c)
        batch, idx, ids, t0s = [], [], [], []
        for name, t0 in todo.items():
            i = self.builder.obj_ids.get(name)
            o, k = by_name.get(name, (None, 0))
            if i is None or o is None:
                continue
            if o.type == 'LIGHT' or name.upper().startswith("OCC_"):
                self.structural = True  # lights and world-space occluders go in the snapshot
                continue
            batch.append(o)
            idx.append(k)
            ids.append(i)
            t0s.append(t0)
        if not batch:
            return
        trs = {}
        for i, t0, t in zip(ids, t0s, self.builder.trs_many(batch, sc.all_world_matrices()[idx])):
            if t is not None:
                trs[i] = (t[0], t[1], t[2], t0)
        if trs:
            self.link.offer_transforms(trs)

    # ---- selection both ways ------------------------------------------------------------
    def share_selection(self, now):
        ids = self.builder.selected_ids(bpy.context.view_layer)
        if ids == self.sel_sent:
            self.sel_seen = (None, 0.0)
            return
        if self.sel_seen[0] != ids:
            self.sel_seen = (ids, now)
            return
        if now - self.sel_seen[1] >= SELECT_DEBOUNCE:
            self.sel_sent = ids
            self.link.offer_selection(ids)

    def apply_selection(self, s):
        """SELECTED from another client: Blender's selection becomes it"""
        self.remote_selection = (s["client_id"], s["ids"])
        want = set(s["ids"])
        names = self.builder.names
        vl = bpy.context.view_layer
        self.applying_selection = True
        try:
            for o in vl.objects:
                i = self.builder.obj_ids.get(o.name)
                sel = i in want
                if o.select_get() != sel:
                    o.select_set(sel)
            act = next((names[i] for i in s["ids"] if i in names), None)
            if act is not None and act in vl.objects:
                vl.objects.active = vl.objects[act]
        finally:
            self.applying_selection = False
        # not echoed back: this is now what we have sent
        self.sel_sent = self.builder.selected_ids(vl)

    # ---- scripts and tests ------------------------------------------------------------
    def synced(self):
        return (self.status == "live" and not self.structural and not self.need_full and not self.dirty_xf
                and not self.full_later and not self.builder.mesh_retry and self.sel_seen[0] is None
                and self.builder.selected_ids(bpy.context.view_layer) == self.sel_sent and self.link.idle())

    def wait_synced(self, timeout=30.0, update=True):
        """pump the flush until everything Blender has is acknowledged by the
        daemon (a background script's stand-in for the timer); False on timeout"""
        if update:
            bpy.context.view_layer.update()
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.tick()
            if self.synced():
                return True
            if self.status == "refused":
                return False
            time.sleep(0.002)
        return False


# The handlers and the timer are module functions marked persistent (a
# bound method cannot be): opening another file keeps the link mirroring,
# and load_post makes it diff the new file against the daemon.
_active = None


@bpy.app.handlers.persistent
def _on_depsgraph(scene, depsgraph):
    if _active is not None:
        _active.on_depsgraph(scene, depsgraph)


@bpy.app.handlers.persistent
def _on_undo(*args):
    if _active is not None:
        _active.on_undo()


def _handlers():
    H = bpy.app.handlers
    return [(H.depsgraph_update_post, _on_depsgraph), (H.undo_post, _on_undo), (H.redo_post, _on_undo),
            (H.load_post, _on_undo)]


def _timer():
    m = _active
    if m is None or not m.running:
        return None
    try:
        m.tick()
    except Exception as e:  # a bug here must not stop the timer and with it the link
        m.log("internal error in the flush: %r" % (e,), error=True)
    return TICK


def _redraw():
    """the sidebar panel shows the new status (no UI in background mode)"""
    if bpy.app.background:
        return
    for win in bpy.context.window_manager.windows:
        for area in win.screen.areas:
            if area.type == 'VIEW_3D':
                area.tag_redraw()


def _exclusions(lc):
    out = []

    def walk(c):
        if c.exclude:
            out.append(c.name)
        for ch in c.children:
            walk(ch)
    walk(lc)
    return tuple(out)
