"""Vantage live-link: mirrors the open Blender scene into a running vantaged
as the artist works (objects, transforms, meshes, materials, textures,
lights, the world, collections as sub-levels, occluders, the selection).

This file owns the add-on's face: bl_info, the preferences (host, port or
Unix socket, token), the 3D view's sidebar panel (status, the last
errors, connect and disconnect), the operators, and a small Python API for
scripts and tests (`connect`, `disconnect`, `current`). The work is in
codec.py (the protocol), link.py (the connection thread and the diff),
scene.py (Blender -> protocol records), mirror.py (handlers and the flush)
and convert.py (axes, transforms, units).
"""
bl_info = {
    "name": "Vantage live-link",
    "author": "Vantage",
    "version": (1, 0, 0),
    "blender": (3, 0, 0),
    "location": "3D View > Sidebar > Vantage",
    "description": "Mirror the scene into a Vantage daemon (vantaged) as you edit",
    "category": "Import-Export",
}

import bpy  # noqa: E402

from . import codec, mirror  # noqa: E402

_mirror = None


def current():
    """the running Mirror, or None"""
    return _mirror


def connect(host="127.0.0.1", port=7470, unix="", token="", role=codec.ROLE_EDITOR, name="blender"):
    """starts mirroring to a daemon (replacing any link running); returns the Mirror"""
    global _mirror
    disconnect()
    _mirror = mirror.Mirror(host, port, unix, token, role=role, name=name)
    _mirror.start()
    return _mirror


def disconnect():
    global _mirror
    if _mirror is not None:
        _mirror.stop()
        _mirror = None


class VantagePreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    host: bpy.props.StringProperty(name="Host", default="127.0.0.1",
                                   description="the daemon's address (vantaged --bind)")
    port: bpy.props.IntProperty(name="Port", default=7470, min=1, max=65535, description="vantaged --port")
    unix: bpy.props.StringProperty(name="Unix socket", default="", subtype='FILE_PATH',
                                   description="a Unix socket path (vantaged --unix); used instead of host and port "
                                               "when set")
    token: bpy.props.StringProperty(name="Token", default="", subtype='PASSWORD',
                                    description="an editor token from the daemon's --tokens file (empty when the "
                                                "daemon has none)")

    def draw(self, context):
        col = self.layout.column()
        col.prop(self, "host")
        col.prop(self, "port")
        col.prop(self, "unix")
        col.prop(self, "token")


def _prefs(context):
    a = context.preferences.addons.get(__package__)
    return a.preferences if a is not None else None


class VANTAGE_OT_connect(bpy.types.Operator):
    bl_idname = "vantage.connect"
    bl_label = "Connect"
    bl_description = "Connect to vantaged and mirror this scene"

    def execute(self, context):
        p = _prefs(context)
        if p is None:
            self.report({'ERROR'}, "Vantage live-link: enable the add-on in Preferences first")
            return {'CANCELLED'}
        connect(p.host, p.port, p.unix, p.token)
        return {'FINISHED'}


class VANTAGE_OT_disconnect(bpy.types.Operator):
    bl_idname = "vantage.disconnect"
    bl_label = "Disconnect"

    def execute(self, context):
        disconnect()
        return {'FINISHED'}


class VANTAGE_PT_panel(bpy.types.Panel):
    bl_label = "Vantage live-link"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Vantage"

    def draw(self, context):
        lay = self.layout
        p = _prefs(context)
        m = _mirror
        if p is not None:
            col = lay.column(align=True)
            col.enabled = m is None
            col.prop(p, "host")
            col.prop(p, "port")
            col.prop(p, "unix")
            col.prop(p, "token")
        if m is None:
            lay.operator("vantage.connect", icon='LINKED')
            return
        lay.operator("vantage.disconnect", icon='UNLINKED')
        lay.label(text="Status: %s" % m.status)
        st = m.link
        lay.label(text="Pending moves: %d   epoch %d" % (st.pending(), st.epoch))
        if m.last_error:
            box = lay.box()
            box.alert = True
            for chunk in _wrap(m.last_error, 48)[:6]:
                box.label(text=chunk)
        if m.remote_selection:
            lay.label(text="Selected by client %d: %d objects" % (m.remote_selection[0], len(m.remote_selection[1])))
        for line in m.log_lines[-4:]:
            lay.label(text=line[:80])


def _wrap(s, n):
    words, out, cur = s.split(), [], ""
    for w in words:
        if len(cur) + len(w) + 1 > n and cur:
            out.append(cur)
            cur = w
        else:
            cur = (cur + " " + w).strip()
    if cur:
        out.append(cur)
    return out


_classes = (VantagePreferences, VANTAGE_OT_connect, VANTAGE_OT_disconnect, VANTAGE_PT_panel)


def register():
    for c in _classes:
        bpy.utils.register_class(c)


def unregister():
    disconnect()
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
