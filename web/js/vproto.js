/*
 * vproto.js — the Vantage wire protocol (protocol/PROTOCOL.md, version 2)
 * for JavaScript: the browser pages (viewer, commander) and Node speak it
 * with this one ES module, unchanged. No dependencies; nothing here touches
 * the DOM or Node's APIs (the transports are passed in).
 *
 * What it owns:
 *   * the byte layer: Writer / Reader (little-endian), the 12-byte frame
 *     header, and FrameParser, which cuts a byte stream that arrives in any
 *     chunking (a WebSocket message may hold several frames or part of one)
 *     into whole frames and refuses a header the stream cannot survive
 *     (non-zero flags, a length over the limit);
 *   * the messages a viewer and a commander send and receive, each fixed
 *     layout described once (LAYOUTS) and encoded / decoded by one generic
 *     pair of functions over it, as protocol/vp_layout.h does in C;
 *   * Client: request ids, one promise per request (resolved by the reply
 *     with its req, rejected with a VpError by ERROR, by a timeout, or when
 *     the connection closes), pushed EVENT / MARKED / FRAME as callbacks;
 *   * wsTransport(url): the browser's WebSocket as a transport;
 *   * views: a camera (eye, target, up, fov, near, far, viewport) as the
 *     160-byte vp_view, computed exactly as client/lib's
 *     vtc_view_perspective / vtc_view_ortho (culling/cull_mat.h), so the
 *     page, the CLI and the commander send the same bytes for one camera.
 *
 * Numbers: u64 fields (ids, epochs, cursors) decode as BigInt, because
 * entity ids use all 64 bits (2^63 | sublevel << 32 | index); encoders
 * take a BigInt or a safe non-negative integer Number. Every other field is
 * a Number.
 *
 * Costs: a frame that arrives inside one chunk is handed on as a view of
 * that chunk (no copy); one split over chunks is copied once into a buffer
 * of its exact size. FRAME pixels (`data`) are a view of the frame's bytes.
 */

// ---- constants (protocol/protocol.h) --------------------------------------------------

export const VP_MAGIC = 0x47544e56; // the bytes "VNTG"
export const VP_VERSION = 2;
export const VP_HEADER_SIZE = 12;
export const VP_VIEW_SIZE = 160;
export const VP_ENTITY_REC_SIZE = 160;
export const VP_VIS_REC_SIZE = 24;
export const VP_FRAME_HEADER = 32;
export const VP_MAX_VIEWS = 32;
export const VP_MAX_PING = 1024;
export const VP_HELLO_MAX_PAYLOAD = 4096; // the server's limit before HELLO_OK
export const VP_RENDER_MAX_HIGHLIGHT = 8;
export const VP_FRAME_SUB_MAX_FPS = 240;

export const VP_FRAME_RAW = 0;
export const VP_FRAME_JPEG = 1;
export const VP_FRAME_H264 = 2; // Annex B, one encoder output per FRAME (issue 21)

export const VP_RENDERER_DEFAULT = 0;
export const VP_RENDERER_SOFT = 1;
export const VP_RENDERER_GL = 2;

export const VP_RENDER_NO_OCCLUSION = 0x01;
export const VP_RENDER_NO_SHADOWS = 0x02;
export const VP_RENDER_NO_SSAO = 0x04;
export const VP_RENDER_NO_IBL = 0x08;
export const VP_RENDER_NO_FXAA = 0x10;
export const VP_RENDER_NO_SELECTION = 0x20; // the shared selection (SELECT) not outlined
export const VP_RENDER_MOTION = 0x40; // FRAME_SUBSCRIBE: drawn smaller while the view moves (vantaged --motion-ms)

export const VP_EVENT_SCENE = 0x1; // SUBSCRIBE kinds
export const VP_EVENT_MARKS = 0x2;
export const VP_EVENT_SELECTION = 0x4; // SELECTED pushes (the current one right after the ACK)

export const VP_Q_NO_AABB = 0x01; // VIS_QUERY flags
export const VP_Q_WANT_AREA = 0x02;
export const VP_Q_NO_OCCLUSION = 0x04;
export const VP_Q_STATIC_ONLY = 0x08;
export const VP_Q_DYNAMIC_ONLY = 0x10;
export const VP_Q_COUNT_ONLY = 0x20;
export const VP_Q_OCC_CENTRE = 0x40;
export const VP_Q_SUBLEVELS = 0x80;

export const VP_ENT_DYNAMIC = 0x1;
export const VP_ENT_TRANSFORM = 0x2;

export const ROLE = Object.freeze({ VIEWER: 0, COMMANDER: 1, EDITOR: 2 });
export const DEPTH = Object.freeze({ GL: 0, ZERO_ONE: 1, REVERSED: 2 });
export const SUBLEVEL_STATE = Object.freeze(['empty', 'loaded', 'loading', 'unloading']);

/* Message types (PROTOCOL.md "Message types"). */
export const T = Object.freeze({
  HELLO: 0x0001, HELLO_OK: 0x0002, ERROR: 0x0003, PING: 0x0004, PONG: 0x0005,
  STATS: 0x0006, STATS_REPLY: 0x0007, SUBSCRIBE: 0x0008, EVENT: 0x0009, ACK: 0x000a,
  ENTITY_ADD: 0x0100, ENTITY_ADD_REPLY: 0x0101, ENTITY_UPDATE: 0x0102, ENTITY_REMOVE: 0x0103,
  ENTITY_LIST: 0x0104, ENTITY_LIST_REPLY: 0x0105, ENTITY_GET: 0x0106, TRANSFORM_SET: 0x0107,
  MESH_PUT: 0x0110, MESH_GET: 0x0111, MESH_REPLY: 0x0112,
  OCCLUDER_PUT: 0x0120, OCCLUDER_REMOVE: 0x0121,
  LIGHT_PUT: 0x0130, LIGHT_REMOVE: 0x0131, LIGHT_LIST: 0x0132, LIGHT_LIST_REPLY: 0x0133,
  MATERIAL_PUT: 0x0140, MATERIAL_REMOVE: 0x0141, MATERIAL_LIST: 0x0142, MATERIAL_LIST_REPLY: 0x0143,
  TEXTURE_PUT: 0x0150, TEXTURE_REMOVE: 0x0151, TEXTURE_GET: 0x0152, TEXTURE_REPLY: 0x0153,
  ENV_SET: 0x0160, ENV_GET: 0x0161, ENV_REPLY: 0x0162,
  VIS_QUERY: 0x0200, VIS_RESULT: 0x0201, LIGHT_QUERY: 0x0202, LIGHT_TILES: 0x0203,
  SUBLEVEL_NAMES: 0x0300, SUBLEVEL_IDS: 0x0301, SUBLEVEL_LIST: 0x0302, SUBLEVEL_LIST_REPLY: 0x0303,
  SUBLEVEL_BEGIN: 0x0304, SUBLEVEL_BEGUN: 0x0305, SUBLEVEL_COMMIT: 0x0306, SUBLEVEL_ABORT: 0x0307,
  SUBLEVEL_UNLOAD: 0x0308, SUBLEVEL_INFO: 0x0309, SUBLEVEL_INFO_REPLY: 0x030a,
  DESTROY: 0x0400, DESTROYED: 0x0401,
  RENDER: 0x0500, FRAME: 0x0501, FRAME_SUBSCRIBE: 0x0502, FRAME_UNSUBSCRIBE: 0x0503,
  MARK: 0x0600, MARKED: 0x0601, SELECT: 0x0602, SELECTED: 0x0603, METRICS: 0x0700, METRICS_REPLY: 0x0701,
});
const TYPE_NAME = new Map(Object.entries(T).map(([k, v]) => [v, k]));
/* "FRAME" for 0x0501, "0x1234" for a type no table row names. */
export function typeName(type) {
  return TYPE_NAME.get(type) ?? `0x${type.toString(16).padStart(4, '0')}`;
}

/* Error codes, named as protocol/protocol.h's VP_ERRORS (VP_ERR_<NAME>). */
export const ERR = Object.freeze({
  MAGIC: -1, VERSION: -2, TOO_LARGE: -3, TRUNCATED: -4, TRAILING: -5, TYPE: -6, COUNT: -7,
  NONFINITE: -8, INVALID: -9, STATE: -10, AUTH: -11, UNKNOWN_ID: -12, STALE: -13, DUPLICATE: -14,
  LIMIT: -15, SCENE: -16, MATRIX: -17, BUSY: -18, INTERNAL: -19, UNSUPPORTED: -20, TIMEOUT: -21,
  IO: -22, NOT_FOUND: -23, NOT_WRITER: -24,
});
const ERR_NAME = new Map(Object.entries(ERR).map(([k, v]) => [v, k]));
/* "AUTH" for -11; "CODE_<n>" for a code no row names (a newer server's). */
export function errName(code) {
  return ERR_NAME.get(code) ?? `CODE_${code}`;
}

/*
 * The one error type of the module. `code` is the protocol's number (ERR.*;
 * a server's code no row names keeps its number, named "CODE_<n>"), null
 * for CLOSED (the connection ended before the reply); `codeName` is its
 * name ("AUTH", "TRUNCATED", ... "CLOSED"); `index` the record a batch
 * error names (0xFFFFFFFF for none); `local` is true when this side found
 * the fault (bytes it could not decode, a value it cannot encode, a
 * request that timed out) rather than the server's ERROR; `req` the
 * request it answers (0 when none).
 */
export class VpError extends Error {
  constructor(codeName, message, { index = 0xffffffff, local = true, req = 0, code = ERR[codeName] ?? null } = {}) {
    super(`${codeName}: ${message}`);
    this.name = 'VpError';
    this.code = code;
    this.codeName = codeName;
    this.index = index;
    this.local = local;
    this.req = req;
  }
}
const fail = (codeName, message) => {
  throw new VpError(codeName, message);
};

// ---- bytes ------------------------------------------------------------------------------

const utf8enc = new TextEncoder();
const utf8dec = new TextDecoder('utf-8', { fatal: false });

/* Bytes of v as a Uint8Array view: a Uint8Array (a Node Buffer included),
 * an ArrayBuffer or another typed array. Nothing is copied. */
export function asBytes(v) {
  if (v instanceof Uint8Array) return v.constructor === Uint8Array ? v : new Uint8Array(v.buffer, v.byteOffset, v.byteLength);
  if (v instanceof ArrayBuffer) return new Uint8Array(v);
  if (ArrayBuffer.isView(v)) return new Uint8Array(v.buffer, v.byteOffset, v.byteLength);
  return fail('INVALID', `expected bytes, got ${typeof v}`);
}

const INT_RANGE = { u8: [0, 0xff], u16: [0, 0xffff], u32: [0, 0xffffffff], i32: [-0x80000000, 0x7fffffff] };

/* A growable little-endian byte writer. Values are checked before they are
 * written: an integer out of its type's range, a non-number or a u64 that
 * is neither a BigInt nor a safe integer throws VpError INVALID naming
 * `what`, so a bad value never goes out silently wrapped. */
export class Writer {
  constructor(cap = 256) {
    this.u8a = new Uint8Array(cap);
    this.dv = new DataView(this.u8a.buffer);
    this.len = 0;
    this.start = -1;
  }
  reserve(n) {
    if (this.len + n > this.u8a.length) {
      let cap = this.u8a.length * 2;
      while (cap < this.len + n) cap *= 2;
      const b = new Uint8Array(cap);
      b.set(this.u8a.subarray(0, this.len));
      this.u8a = b;
      this.dv = new DataView(b.buffer);
    }
    const at = this.len;
    this.len += n;
    return at;
  }
  int(type, v, what = type) {
    const [lo, hi] = INT_RANGE[type];
    if (!Number.isInteger(v) || v < lo || v > hi) fail('INVALID', `${what} ${String(v)} is not an integer in ${lo}..${hi}`);
    const at = this.reserve(type === 'u8' ? 1 : type === 'u16' ? 2 : 4);
    if (type === 'u8') this.dv.setUint8(at, v);
    else if (type === 'u16') this.dv.setUint16(at, v, true);
    else if (type === 'u32') this.dv.setUint32(at, v, true);
    else this.dv.setInt32(at, v, true);
  }
  u8(v, what) { this.int('u8', v, what); }
  u16(v, what) { this.int('u16', v, what); }
  u32(v, what) { this.int('u32', v, what); }
  i32(v, what) { this.int('i32', v, what); }
  u64(v, what = 'u64') {
    let b;
    if (typeof v === 'bigint') b = v;
    else if (Number.isSafeInteger(v)) b = BigInt(v);
    else fail('INVALID', `${what} ${String(v)} is not a BigInt or a safe integer`);
    if (b < 0n || b > 0xffffffffffffffffn) fail('INVALID', `${what} ${b} is outside 0..2^64-1`);
    const at = this.reserve(8); // first: it may replace this.dv
    this.dv.setBigUint64(at, b, true);
  }
  f32(v, what = 'f32') {
    if (typeof v !== 'number') fail('INVALID', `${what} is not a number (${typeof v})`);
    const at = this.reserve(4);
    this.dv.setFloat32(at, v, true);
  }
  f64(v, what = 'f64') {
    if (typeof v !== 'number') fail('INVALID', `${what} is not a number (${typeof v})`);
    const at = this.reserve(8);
    this.dv.setFloat64(at, v, true);
  }
  bytes(b) {
    b = asBytes(b);
    const at = this.reserve(b.length);
    this.u8a.set(b, at);
  }
  zeros(n) {
    const at = this.reserve(n);
    this.u8a.fill(0, at, this.len);
  }
  /* A frame's header (len patched by end()). */
  begin(type, req) {
    this.start = this.len;
    this.u32(0);
    this.u16(type, 'type');
    this.u16(0);
    this.u32(req, 'req');
  }
  end() {
    this.dv.setUint32(this.start, this.len - this.start - VP_HEADER_SIZE, true);
    this.start = -1;
  }
  /* What was written, as a view (valid until the next write). */
  view() {
    return this.u8a.subarray(0, this.len);
  }
}

/* A little-endian reader over bytes. A read past the end throws VpError
 * TRUNCATED; finish() throws TRAILING when bytes are left. */
export class Reader {
  constructor(bytes) {
    this.b = asBytes(bytes);
    this.dv = new DataView(this.b.buffer, this.b.byteOffset, this.b.byteLength);
    this.pos = 0;
  }
  get left() { return this.b.length - this.pos; }
  take(n, what = 'field') {
    if (n > this.left) fail('TRUNCATED', `${what} needs ${n} bytes, ${this.left} left`);
    const at = this.pos;
    this.pos += n;
    return at;
  }
  u8(w) { return this.dv.getUint8(this.take(1, w)); }
  u16(w) { return this.dv.getUint16(this.take(2, w), true); }
  u32(w) { return this.dv.getUint32(this.take(4, w), true); }
  i32(w) { return this.dv.getInt32(this.take(4, w), true); }
  u64(w) { return this.dv.getBigUint64(this.take(8, w), true); }
  f32(w) { return this.dv.getFloat32(this.take(4, w), true); }
  f64(w) { return this.dv.getFloat64(this.take(8, w), true); }
  /* n bytes as a view of the input (not copied). */
  bytes(n, w) {
    const at = this.take(n, w);
    return this.b.subarray(at, at + n);
  }
  finish(what = 'message') {
    if (this.left) fail('TRAILING', `${this.left} bytes after the ${what}`);
  }
}

// ---- the stream -------------------------------------------------------------------------

/* The largest payload FrameParser takes by default: the daemon's default
 * --out-limit (256 MiB; a reply it could not buffer is never sent) plus a
 * FRAME header. A page that never asks for RAW frames may pass far less. */
export const DEFAULT_MAX_PAYLOAD = 256 * 1024 * 1024 + VP_FRAME_HEADER;

/*
 * Cuts a byte stream into frames. push(chunk) takes the next bytes (any
 * length, 0 included) and returns the frames completed by them, in order:
 * { type, flags, req, payload } with payload a Uint8Array of exactly the
 * frame's length. A payload inside one chunk views that chunk, so the
 * caller must not reuse a chunk's memory after pushing it (WebSocket
 * messages and Node's socket chunks are fresh buffers).
 *
 * A header with non-zero flags (INVALID) or a length over maxPayload
 * (TOO_LARGE) throws VpError: a length that cannot be trusted leaves no
 * frame boundary to resync on, so the parser stays failed and every later
 * push throws the same error. Frames completed in the same chunk before
 * the bad header are still returned by that push's `frames` in the error
 * (err.frames).
 */
export class FrameParser {
  constructor({ maxPayload = DEFAULT_MAX_PAYLOAD } = {}) {
    this.maxPayload = maxPayload;
    this.head = new Uint8Array(VP_HEADER_SIZE); // a header split over chunks
    this.headLen = 0;
    this.cur = null; // { type, flags, req, payload (being filled) }
    this.filled = 0;
    this.error = null;
  }
  /* Bytes held for a frame not yet complete. */
  get buffered() {
    return this.cur ? VP_HEADER_SIZE + this.filled : this.headLen;
  }
  header(b, at) {
    const dv = new DataView(b.buffer, b.byteOffset + at, VP_HEADER_SIZE);
    const len = dv.getUint32(0, true), type = dv.getUint16(4, true), flags = dv.getUint16(6, true);
    const req = dv.getUint32(8, true);
    if (flags !== 0) this.error = new VpError('INVALID', `frame ${typeName(type)} (req ${req}) has flags 0x${flags.toString(16)}; they must be 0`);
    else if (len > this.maxPayload) this.error = new VpError('TOO_LARGE', `frame ${typeName(type)} (req ${req}) of ${len} bytes is over the limit of ${this.maxPayload}`);
    return { len, type, flags, req };
  }
  push(chunk) {
    if (this.error) {
      this.error.frames = []; // those were handed on by the push that failed
      throw this.error;
    }
    const b = asBytes(chunk);
    const out = [];
    let i = 0;
    while (i < b.length) {
      if (this.cur) { // filling a payload begun in an earlier chunk
        const n = Math.min(b.length - i, this.cur.payload.length - this.filled);
        this.cur.payload.set(b.subarray(i, i + n), this.filled);
        this.filled += n;
        i += n;
        if (this.filled === this.cur.payload.length) {
          out.push(this.cur);
          this.cur = null;
        }
        continue;
      }
      let h;
      if (this.headLen === 0 && b.length - i >= VP_HEADER_SIZE) {
        h = this.header(b, i);
        i += VP_HEADER_SIZE;
      } else { // a header split over chunks
        const n = Math.min(b.length - i, VP_HEADER_SIZE - this.headLen);
        this.head.set(b.subarray(i, i + n), this.headLen);
        this.headLen += n;
        i += n;
        if (this.headLen < VP_HEADER_SIZE) break;
        this.headLen = 0;
        h = this.header(this.head, 0);
      }
      if (this.error) {
        this.error.frames = out;
        throw this.error;
      }
      const frame = { type: h.type, flags: h.flags, req: h.req, payload: null };
      if (b.length - i >= h.len) { // whole in this chunk: a view, no copy
        frame.payload = b.subarray(i, i + h.len);
        i += h.len;
        out.push(frame);
      } else {
        frame.payload = new Uint8Array(h.len);
        this.cur = frame;
        this.filled = 0;
      }
    }
    return out;
  }
}

// ---- layouts: each fixed record described once ------------------------------------------

/*
 * A layout is a list of "name type" fields: type u8 u16 u32 u64 i32 f32
 * f64, optionally [n] for an array, or pad(n) for n bytes written as 0 and
 * not read. The names are PROTOCOL.md's (tests/web checks every layout
 * against the file's `<!-- layout: name -->` tables).
 */
const SIZES = { u8: 1, u16: 2, u32: 4, u64: 8, i32: 4, f32: 4, f64: 8 };
function layout(spec) {
  let off = 0;
  const fields = spec.split(',').map((s) => s.trim()).map((s) => {
    const pad = /^pad\((\d+)\)$/.exec(s);
    const f = pad ? { name: 'pad', type: 'pad', count: 0, size: +pad[1] }
      : (() => {
        const m = /^(\w+) (u8|u16|u32|u64|i32|f32|f64)(?:\[(\d+)\])?$/.exec(s);
        if (!m) throw new Error(`vproto: bad layout field "${s}"`);
        return { name: m[1], type: m[2], count: m[3] ? +m[3] : 0, size: SIZES[m[2]] * (m[3] ? +m[3] : 1) };
      })();
    f.offset = off;
    off += f.size;
    return f;
  });
  return Object.freeze({ fields, size: off });
}

export const LAYOUTS = Object.freeze({
  hello_ok: layout('version u16, role u8, pad(1), max_payload u32, max_batch u32, max_views u32, epoch u64, client_id u32'),
  stats_reply: layout('epoch u64, uptime_ms u64, entities u32, static_entities u32, dynamic_entities u32, regions u32, ' +
    'cells u32, connections u32, meshes u32, occluders u32, lights u32, queries u64, edits u64, bytes_in u64, ' +
    'bytes_out u64, errors u64'),
  event: layout('kind u32, pad(4), epoch u64, added u32, updated u32, removed u32'),
  ack: layout('epoch u64, count u32'),
  entity: layout('id u64, handle u32, class_id u16, sublevel u16, flags u32, material u32, pos f64[3], rot f32[4], ' +
    'scale f32[3], pad(4), sphere f64[4], aabb f64[6]'),
  list_reply: layout('next_cursor u64, epoch u64, count u32'),
  view: layout('origin f64[3], view_proj f64[16], depth_mode u8, pad(1), viewport_w u16, viewport_h u16, pad(2)'),
  vis_query: layout('view_count u8, flags u8, pad(2), min_area f32'),
  vis_result: layout('epoch u64, tested u32, visible u32, stage_ns u32[6], count u32'),
  vis_rec: layout('id u64, handle u32, view_mask u32, class_id u16, sublevel u16, area f32'),
  render_tail: layout('format u8, quality u8, flags u8, renderer u8, exposure_ev f32, nhighlight u8, pad(3), max_kbps u32, highlight u64[8]'),
  frame_sub_tail: layout('max_fps u16, view_seq u16'),
  frame: layout('epoch u64, width u16, height u16, format u8, key u8, view_seq u16, visible u32, render_ns u32, ' +
    'encode_ns u32, data_len u32'),
  mark: layout('pos f64[3], entity u64, kind u8, pad(3), ttl_ms u32'),
  marked_head: layout('client_id u32, pad(4)'),
  select_head: layout('count u32, flags u32'),
  selected_head: layout('client_id u32, count u32, serial u64'),
  destroy: layout('id u64, handle u32, debris u8, pad(3), center f64[3], radius f64'),
  destroyed: layout('epoch u64, spheres u32, occluder_tris u32, debris u32, cut_us u32'),
  env: layout('sun_dir f32[3], sun_color f32[3], sun_lux f32, sky_mode u8, flags u8, exposure_mode u8, pad(1), ' +
    'sky_color f32[3], sky_intensity f32, turbidity f32, sky_texture u32, sky_rotation f32, pad(4), ' +
    'ground_height f64, ground_color f32[3], ground_material u32, fog_density f32, fog_color f32[3], ' +
    'fog_height_falloff f32, exposure_ev f32, exposure_comp f32, pad(4)'),
});

const ZERO = { u64: 0n };
/* Writes obj's fields in layout L. A field obj lacks is 0 (arrays: all 0),
 * so a desc names only what it sets; `what` prefixes error messages. */
export function putLayout(w, L, obj = {}, what = '') {
  for (const f of L.fields) {
    if (f.type === 'pad') {
      w.zeros(f.size);
      continue;
    }
    const name = what ? `${what} ${f.name}` : f.name;
    const v = obj[f.name];
    if (f.count) {
      const a = v ?? new Array(f.count).fill(ZERO[f.type] ?? 0);
      if (a.length !== f.count) fail('INVALID', `${name} has ${a.length} elements, not ${f.count}`);
      for (let k = 0; k < f.count; k++) w[f.type](a[k], `${name}[${k}]`);
    } else {
      w[f.type](v ?? ZERO[f.type] ?? 0, name);
    }
  }
}

/* Reads layout L's fields into a new object (pads skipped, not checked:
 * the server writes them 0, and PROTOCOL.md leaves some "not read"). */
export function getLayout(r, L, what = 'record') {
  if (r.left < L.size) fail('TRUNCATED', `${what} needs ${L.size} bytes, ${r.left} left`);
  const o = {};
  for (const f of L.fields) {
    if (f.type === 'pad') r.pos += f.size;
    else if (f.count) {
      o[f.name] = new Array(f.count);
      for (let k = 0; k < f.count; k++) o[f.name][k] = r[f.type]();
    } else o[f.name] = r[f.type]();
  }
  return o;
}

/* A whole payload of exactly layout L. */
function exact(payload, L, what) {
  const r = new Reader(payload);
  const o = getLayout(r, L, what);
  r.finish(what);
  return o;
}

// ---- encoders: each returns one whole frame (header + payload) --------------------------

/* One frame: the header of type and req, the payload fill(writer) writes
 * (none without fill), the length patched. */
export function encodeFrame(type, req, fill) {
  const w = new Writer();
  w.begin(type, req);
  if (fill) fill(w);
  w.end();
  return w.view();
}

/* A string as its UTF-8 bytes, at most max of them (else INVALID). */
function utf8(s, max, what) {
  const b = typeof s === 'string' ? utf8enc.encode(s) : asBytes(s);
  if (b.length > max) fail('INVALID', `${what} is ${b.length} bytes; at most ${max}`);
  return b;
}

/* An id list (ENTITY_GET, ENTITY_REMOVE): count, then the u64 ids. */
function putIds(w, ids) {
  w.u32(ids.length, 'count');
  ids.forEach((id, i) => w.u64(id, `id ${i}`));
}

/* A list of u8-length names (SUBLEVEL_NAMES). */
function putNames(w, names) {
  w.u32(names.length, 'count');
  names.forEach((n, i) => {
    const b = utf8(n, 255, `name ${i}`);
    w.u8(b.length);
    w.bytes(b);
  });
}

/* A view, as vp_view: { origin[3], view_proj[16] (column-major),
 * depth_mode (DEPTH.*), viewport_w, viewport_h } (viewFromCamera makes one). */
function putView(w, v, what = 'view') {
  putLayout(w, LAYOUTS.view, v, what);
}

/* RENDER's 240 bytes: { view, format (VP_FRAME_*), quality (JPEG 1..100,
 * RAW 0, H264 the CRF 1..51 or 0: 23), flags (VP_RENDER_NO_*), renderer,
 * exposure_ev, max_kbps (H264's rate cap, 0: none), highlight: [ids]
 * (at most 8) }. */
function putRender(w, m) {
  putView(w, m.view);
  const hl = m.highlight ?? [];
  if (hl.length > VP_RENDER_MAX_HIGHLIGHT) fail('COUNT', `${hl.length} highlights; at most ${VP_RENDER_MAX_HIGHLIGHT}`);
  const highlight = Array.from({ length: VP_RENDER_MAX_HIGHLIGHT }, (_, i) => (i < hl.length ? hl[i] : 0n));
  putLayout(w, LAYOUTS.render_tail, {
    format: VP_FRAME_JPEG, quality: m.format === VP_FRAME_RAW || m.format === VP_FRAME_H264 ? 0 : 85, ...m,
    nhighlight: hl.length, highlight,
  });
}

export const enc = Object.freeze({
  /* { role (ROLE.*), token (string or bytes, 0..255), name (0..255) } */
  hello(req, { role = ROLE.VIEWER, token = '', name = 'vproto.js' } = {}) {
    return encodeFrame(T.HELLO, req, (w) => {
      const tok = utf8(token, 255, 'token'), nm = utf8(name, 255, 'name');
      w.u32(VP_MAGIC);
      w.u16(VP_VERSION);
      w.u8(role, 'role');
      w.u8(tok.length);
      w.bytes(tok);
      w.u8(nm.length);
      w.bytes(nm);
    });
  },
  ping: (req, data = new Uint8Array(0)) => encodeFrame(T.PING, req, (w) => w.bytes(utf8(data, VP_MAX_PING, 'ping data'))),
  empty: (type, req) => encodeFrame(type, req), // STATS, SUBLEVEL_LIST, SUBLEVEL_INFO, ENV_GET, FRAME_UNSUBSCRIBE
  subscribe: (req, kinds) => encodeFrame(T.SUBSCRIBE, req, (w) => w.u32(kinds, 'kinds')),
  entityGet: (req, ids) => encodeFrame(T.ENTITY_GET, req, (w) => putIds(w, ids)),
  /* views: 1..32 views; { flags (VP_Q_*, VP_Q_SUBLEVELS set by sublevels),
   * minArea (pixels), sublevels: [ids] (only these are seen) } */
  visQuery(req, views, { flags = 0, minArea = 0, sublevels = null } = {}) {
    return encodeFrame(T.VIS_QUERY, req, (w) => {
      const f = sublevels ? flags | VP_Q_SUBLEVELS : flags & ~VP_Q_SUBLEVELS;
      putLayout(w, LAYOUTS.vis_query, { view_count: views.length, flags: f, min_area: minArea });
      views.forEach((v, i) => putView(w, v, `view ${i}`));
      if (sublevels) {
        w.u16(sublevels.length, 'sub-level count');
        sublevels.forEach((s, i) => w.u16(s, `sub-level ${i}`));
      }
    });
  },
  sublevelNames: (req, names) => encodeFrame(T.SUBLEVEL_NAMES, req, (w) => putNames(w, names)),
  /* { pos[3], entity (id, 0 = a place), kind (0 ping, 1 select), ttl_ms } */
  mark: (req, m) => encodeFrame(T.MARK, req, (w) => putLayout(w, LAYOUTS.mark, { ttl_ms: 10000, ...m }, 'mark')),
  /* the shared selection: ids (BigInt or safe integers), 0..256 of them */
  select: (req, ids) => encodeFrame(T.SELECT, req, (w) => {
    putLayout(w, LAYOUTS.select_head, { count: ids.length, flags: 0 }, 'select');
    ids.forEach((id, i) => w.u64(id, `id ${i}`));
  }),
  /* { id, handle (0 = any), debris (0..64), center[3], radius } */
  destroy: (req, m) => encodeFrame(T.DESTROY, req, (w) => putLayout(w, LAYOUTS.destroy, m, 'destroy')),
  render: (req, m) => encodeFrame(T.RENDER, req, (w) => putRender(w, m)),
  /* any type with any payload bytes, as they are (tests send bad frames) */
  raw: (type, req, payload = new Uint8Array(0)) => encodeFrame(type, req, (w) => w.bytes(payload)),
  /* RENDER's fields and { maxFps (1..240), viewSeq (u16) } */
  frameSubscribe(req, m) {
    return encodeFrame(T.FRAME_SUBSCRIBE, req, (w) => {
      putRender(w, m);
      putLayout(w, LAYOUTS.frame_sub_tail, { max_fps: m.maxFps ?? 30, view_seq: m.viewSeq ?? 0 });
    });
  },
});

// ---- decoders: payload -> object ------------------------------------------------------

function decError(p) {
  const r = new Reader(p);
  const code = r.i32('code'), index = r.u32('index'), n = r.u16('msg_len');
  if (n > 1024) fail('COUNT', `ERROR message of ${n} bytes; at most 1024`);
  const msg = utf8dec.decode(r.bytes(n, 'message'));
  r.finish('ERROR');
  return { code, codeName: errName(code), index, msg };
}

function decListReply(p) {
  const r = new Reader(p);
  const h = getLayout(r, LAYOUTS.list_reply, 'ENTITY_LIST_REPLY');
  if (r.left !== h.count * VP_ENTITY_REC_SIZE)
    fail('COUNT', `${h.count} entity records need ${h.count * VP_ENTITY_REC_SIZE} bytes, the reply has ${r.left}`);
  h.entities = [];
  for (let i = 0; i < h.count; i++) h.entities.push(getLayout(r, LAYOUTS.entity, `entity ${i}`));
  return h;
}

function decVisResult(p) {
  const r = new Reader(p);
  const h = getLayout(r, LAYOUTS.vis_result, 'VIS_RESULT');
  if (r.left !== h.count * VP_VIS_REC_SIZE)
    fail('COUNT', `${h.count} records need ${h.count * VP_VIS_REC_SIZE} bytes, the reply has ${r.left}`);
  h.records = [];
  for (let i = 0; i < h.count; i++) h.records.push(getLayout(r, LAYOUTS.vis_rec, `record ${i}`));
  return h;
}

/* u32 count, then count x (u16 id, u8 len, name): SUBLEVEL_LIST_REPLY */
function decNames(p) {
  const r = new Reader(p);
  const n = r.u32('count');
  if (n > r.left / 3) fail('COUNT', `${n} names cannot fit ${r.left} bytes`);
  const out = [];
  for (let i = 0; i < n; i++) {
    const id = r.u16(`name ${i} id`);
    out.push({ id, name: utf8dec.decode(r.bytes(r.u8(`name ${i} length`), `name ${i}`)) });
  }
  r.finish('SUBLEVEL_LIST_REPLY');
  return out;
}

function decIds16(p) {
  const r = new Reader(p);
  const n = r.u32('count');
  if (r.left !== n * 2) fail('COUNT', `${n} ids need ${n * 2} bytes, the reply has ${r.left}`);
  return Array.from({ length: n }, () => r.u16());
}

function decInfos(p) {
  const r = new Reader(p);
  const epoch = r.u64('epoch'), n = r.u32('count');
  if (n > r.left / 20) fail('COUNT', `${n} sub-level entries cannot fit ${r.left} bytes`);
  const sublevels = [];
  for (let i = 0; i < n; i++) {
    const e = { id: r.u16(), state: r.u8(), entities: r.u32(), occluders: r.u32(), lights: r.u32(), class_base: r.u16(), classes: r.u16() };
    e.stateName = SUBLEVEL_STATE[e.state] ?? `state ${e.state}`;
    e.name = utf8dec.decode(r.bytes(r.u8(`entry ${i} name length`), `entry ${i} name`));
    sublevels.push(e);
  }
  r.finish('SUBLEVEL_INFO_REPLY');
  return { epoch, sublevels };
}

/* FRAME: the header's fields, and data: a view of the picture's bytes
 * (RAW floats, a JPEG file, or H.264 Annex B: one encoder output). */
function decFrame(p) {
  const r = new Reader(p);
  const f = getLayout(r, LAYOUTS.frame, 'FRAME');
  if (f.format > VP_FRAME_H264) fail('INVALID', `FRAME format ${f.format}: 0 raw, 1 JPEG, 2 H.264 are defined`);
  if (!f.width || !f.height) fail('INVALID', `FRAME of ${f.width} x ${f.height} pixels`);
  if (r.left < f.data_len) fail('TRUNCATED', `FRAME data_len ${f.data_len}, ${r.left} bytes follow`);
  if (r.left > f.data_len) fail('TRAILING', `FRAME data_len ${f.data_len}, ${r.left} bytes follow`);
  if (f.format === VP_FRAME_RAW && f.data_len !== f.width * f.height * 20)
    fail('COUNT', `RAW FRAME of ${f.width} x ${f.height} needs ${f.width * f.height * 20} bytes, has ${f.data_len}`);
  f.data = r.bytes(f.data_len);
  return f;
}

function decMarked(p) {
  const r = new Reader(p);
  const h = getLayout(r, LAYOUTS.marked_head, 'MARKED');
  h.mark = getLayout(r, LAYOUTS.mark, 'MARKED mark');
  r.finish('MARKED');
  return h;
}

/* SELECTED: { client_id, count, serial, ids: [BigInt] } */
function decSelected(p) {
  const r = new Reader(p);
  const h = getLayout(r, LAYOUTS.selected_head, 'SELECTED');
  if (h.count > 256) fail('COUNT', `SELECTED of ${h.count} ids: at most 256`);
  if (r.left !== h.count * 8) fail('COUNT', `SELECTED of ${h.count} ids needs ${h.count * 8} bytes, has ${r.left}`);
  h.ids = Array.from({ length: h.count }, () => r.u64());
  return h;
}

/* type -> payload decoder, for every reply and push the Client handles. */
export const dec = Object.freeze({
  [T.HELLO_OK]: (p) => exact(p, LAYOUTS.hello_ok, 'HELLO_OK'),
  [T.ERROR]: decError,
  [T.PONG]: (p) => p,
  [T.STATS_REPLY]: (p) => exact(p, LAYOUTS.stats_reply, 'STATS_REPLY'),
  [T.EVENT]: (p) => exact(p, LAYOUTS.event, 'EVENT'),
  [T.ACK]: (p) => exact(p, LAYOUTS.ack, 'ACK'),
  [T.ENTITY_LIST_REPLY]: decListReply,
  [T.VIS_RESULT]: decVisResult,
  [T.SUBLEVEL_IDS]: decIds16,
  [T.SUBLEVEL_LIST_REPLY]: decNames,
  [T.SUBLEVEL_INFO_REPLY]: decInfos,
  [T.DESTROYED]: (p) => exact(p, LAYOUTS.destroyed, 'DESTROYED'),
  [T.MARKED]: decMarked,
  [T.SELECTED]: decSelected,
  [T.FRAME]: decFrame,
  [T.ENV_REPLY]: (p) => exact(p, LAYOUTS.env, 'ENV_REPLY'),
});

/* A frame's payload decoded by its type: throws VpError for bytes that do
 * not hold the message, TYPE for a type this module does not decode. */
export function decode(type, payload) {
  const d = dec[type];
  if (!d) fail('TYPE', `no decoder for ${typeName(type)}`);
  return d(payload);
}

// ---- views (client/lib vtc_view_perspective / vtc_view_ortho, culling/cull_mat.h) -------
// The same operations in the same order in binary64, so each double is the
// one the C code computes (no FMA: the client library is built without it).

function normalize3(v) {
  const l = Math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (l > 0) {
    v[0] /= l;
    v[1] /= l;
    v[2] /= l;
  }
}

function lookDir(dir, up) { // cull_mat_look_dir
  const f = [dir[0], dir[1], dir[2]];
  normalize3(f);
  const s = [f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2], f[0] * up[1] - f[1] * up[0]];
  normalize3(s);
  const u = [s[1] * f[2] - s[2] * f[1], s[2] * f[0] - s[0] * f[2], s[0] * f[1] - s[1] * f[0]];
  const m = new Array(16).fill(0);
  for (let i = 0; i < 3; i++) {
    m[i * 4 + 0] = s[i];
    m[i * 4 + 1] = u[i];
    m[i * 4 + 2] = -f[i];
  }
  m[15] = 1;
  return m;
}

function mul(a, b) { // cull_mat_mul: column-major a * b
  const t = new Array(16);
  for (let c = 0; c < 4; c++)
    for (let r = 0; r < 4; r++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
      t[c * 4 + r] = s;
    }
  return t;
}

function perspective(fovy, aspect, n, f) { // cull_mat_perspective, OpenGL depth
  const m = new Array(16).fill(0);
  const t = 1.0 / Math.tan(0.5 * fovy);
  m[0] = t / aspect;
  m[5] = t;
  m[11] = -1;
  const inf = f === Infinity;
  m[10] = inf ? -1 : (f + n) / (n - f);
  m[14] = inf ? -2 * n : 2 * f * n / (n - f);
  return m;
}

function ortho(l, r, b, t, n, f) { // cull_mat_ortho, OpenGL depth
  const m = new Array(16).fill(0);
  m[0] = 2 / (r - l);
  m[5] = 2 / (t - b);
  m[12] = -(r + l) / (r - l);
  m[13] = -(t + b) / (t - b);
  m[15] = 1;
  m[10] = -2 / (f - n);
  m[14] = -(f + n) / (f - n);
  return m;
}

function num(v, what) {
  if (typeof v !== 'number') fail('INVALID', `${what} is not a number (${typeof v})`);
  return v;
}

function vec3(v, what) {
  if (!Array.isArray(v) && !ArrayBuffer.isView(v)) fail('INVALID', `${what} is not an array of 3 numbers`);
  if (v.length !== 3 || ![0, 1, 2].every((i) => typeof v[i] === 'number')) fail('INVALID', `${what} is not 3 numbers`);
  return [v[0], v[1], v[2]];
}

function camera(eye, target, up, proj, w, h) { // libvantage.c camera()
  const dir = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
  const u = up;
  const cr = [dir[1] * u[2] - dir[2] * u[1], dir[2] * u[0] - dir[0] * u[2], dir[0] * u[1] - dir[1] * u[0]];
  if (!(Math.sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]) > 0) ||
      !(Math.sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]) > 1e-12))
    return null;
  return { origin: [eye[0], eye[1], eye[2]], view_proj: mul(proj, lookDir(dir, u)), depth_mode: DEPTH.GL, viewport_w: w, viewport_h: h };
}

/*
 * A perspective camera as a view: gluLookAt(eye, target, up) and
 * gluPerspective(fovDeg, width / height, near, far), camera-relative
 * (origin = eye), OpenGL depth; width x height the viewport in pixels.
 * The defaults are the CLI's (`vantage render`: up +Y, fov 60, near 0.1,
 * far 10000). Returns null for a camera vtc_view_perspective refuses
 * (eye == target, up parallel to the view, fov outside (0, 180), a
 * viewport side 0, near <= 0, far <= near); throws INVALID for arguments
 * that are not numbers or a viewport side outside 1..65535.
 */
export function viewPerspective({ eye, target, up = [0, 1, 0], fovDeg = 60, width, height, near = 0.1, far = 10000 }) {
  const e = vec3(eye, 'eye'), t = vec3(target, 'target'), u = vec3(up, 'up');
  const w = viewportSide(width, 'width'), h = viewportSide(height, 'height');
  [fovDeg, near, far].forEach((v, i) => num(v, ['fovDeg', 'near', 'far'][i]));
  if (!(fovDeg > 0 && fovDeg < 180) || !w || !h || !(near > 0) || !(far > near)) return null;
  return camera(e, t, u, perspective(fovDeg * Math.PI / 180, w / h, near, far), w, h);
}

/* An orthographic camera: a box of widthM x heightM metres about the view
 * axis, near..far along it (vtc_view_ortho; near may be <= 0). null where
 * that refuses. */
export function viewOrtho({ eye, target, up = [0, 1, 0], widthM, heightM, width, height, near = 0.1, far = 10000 }) {
  const e = vec3(eye, 'eye'), t = vec3(target, 'target'), u = vec3(up, 'up');
  const w = viewportSide(width, 'width'), h = viewportSide(height, 'height');
  [widthM, heightM, near, far].forEach((v, i) => num(v, ['widthM', 'heightM', 'near', 'far'][i]));
  if (!(widthM > 0) || !(heightM > 0) || !w || !h || !(far > near)) return null;
  return camera(e, t, u, ortho(-widthM / 2, widthM / 2, -heightM / 2, heightM / 2, near, far), w, h);
}

function viewportSide(v, what) {
  if (!Number.isInteger(v) || v < 0 || v > 0xffff) fail('INVALID', `${what} ${String(v)} is not a viewport side in 0..65535`);
  return v;
}

/* A view's 160 bytes, as the wire carries them (tests compare these). */
export function viewBytes(v) {
  const w = new Writer(VP_VIEW_SIZE);
  putView(w, v);
  return w.view();
}

// ---- the client ---------------------------------------------------------------------------

/*
 * A connection speaking the protocol over a transport:
 *   { send(Uint8Array), close(), onbytes, onclose }
 * The Client sets transport.onbytes = (bytes) => ... (any chunking) and
 * transport.onclose = (info) => ...; the transport calls them.
 *
 * Requests return promises: resolved with the decoded reply (its `req`
 * matched), rejected with VpError: the server's ERROR (local false,
 * codeName e.g. "AUTH"), a reply that does not decode or is of the wrong
 * type (local), TIMEOUT after timeoutMs (local; a late reply is then
 * dropped), CLOSED when the connection ends first.
 *
 * Pushed messages go to callbacks the page sets:
 *   onevent(ev)        EVENT (SUBSCRIBE kinds VP_EVENT_SCENE)
 *   onmarked(m)        MARKED (VP_EVENT_MARKS): { client_id, mark }
 *   onselected(s)      SELECTED (VP_EVENT_SELECTION): { client_id, count, serial, ids }
 *   onframe(f, req)    FRAME of a stream (FRAME_SUBSCRIBE's req)
 *   onerror(err)       a pushed ERROR (a stream that ended, a TIMEOUT with
 *                      req 0) or a push that did not decode
 *   onclose(info)      the connection ended (after parse errors too)
 * A callback that throws does not stop the stream: the exception goes to
 * callbackFailed(e) (rethrown from a microtask: the console shows it) and
 * parsing goes on.
 */
export class Client {
  constructor(transport, { timeoutMs = 10000, maxPayload = DEFAULT_MAX_PAYLOAD } = {}) {
    this.t = transport;
    this.timeoutMs = timeoutMs;
    this.parser = new FrameParser({ maxPayload });
    this.pending = new Map(); // req -> { type, resolve, reject, timer }
    this.nextReq = 1;
    this.serverMaxPayload = VP_HELLO_MAX_PAYLOAD; // until HELLO_OK
    this.helloOk = null;
    this.closed = false;
    this.onevent = this.onmarked = this.onselected = this.onframe = this.onerror = this.onclose = null;
    transport.onbytes = (b) => this.bytes(b);
    transport.onclose = (info) => this.ended(info);
  }

  /* HELLO; resolves with HELLO_OK's fields ({ role, max_payload, epoch,
   * client_id, ... }). A refusal (AUTH, VERSION) rejects; the server then
   * closes the connection. */
  async hello({ role = ROLE.VIEWER, token = '', name = 'vproto.js' } = {}, opts) {
    const ok = await this.call(T.HELLO, (req) => enc.hello(req, { role, token, name }), T.HELLO_OK, opts);
    this.helloOk = ok;
    this.serverMaxPayload = ok.max_payload;
    return ok;
  }
  ping(data, opts) { return this.call(T.PING, (req) => enc.ping(req, data), T.PONG, opts); }
  stats(opts) { return this.call(T.STATS, (req) => enc.empty(T.STATS, req), T.STATS_REPLY, opts); }
  /* kinds: VP_EVENT_SCENE | VP_EVENT_MARKS | VP_EVENT_SELECTION (0 unsubscribes); resolves with the ACK */
  subscribe(kinds, opts) { return this.call(T.SUBSCRIBE, (req) => enc.subscribe(req, kinds), T.ACK, opts); }
  /* ids: BigInt or safe integers; resolves { epoch, entities: [records in the order asked] } */
  entityGet(ids, opts) { return this.call(T.ENTITY_GET, (req) => enc.entityGet(req, ids), T.ENTITY_LIST_REPLY, opts); }
  /* resolves VIS_RESULT: { epoch, tested, visible, stage_ns, count, records: [{ id, handle, view_mask, ... }] } */
  visQuery(views, q = {}, opts) { return this.call(T.VIS_QUERY, (req) => enc.visQuery(req, views, q), T.VIS_RESULT, opts); }
  /* editor: names -> ids (defined when new) */
  sublevelNames(names, opts) { return this.call(T.SUBLEVEL_NAMES, (req) => enc.sublevelNames(req, names), T.SUBLEVEL_IDS, opts); }
  /* resolves [{ id, name }] */
  sublevelList(opts) { return this.call(T.SUBLEVEL_LIST, (req) => enc.empty(T.SUBLEVEL_LIST, req), T.SUBLEVEL_LIST_REPLY, opts); }
  /* resolves { epoch, sublevels: [{ id, name, state, stateName, entities, ... }] } */
  sublevelInfo(opts) { return this.call(T.SUBLEVEL_INFO, (req) => enc.empty(T.SUBLEVEL_INFO, req), T.SUBLEVEL_INFO_REPLY, opts); }
  /* commander: resolves the ACK ({ count: connections it went to }) */
  mark(m, opts) { return this.call(T.MARK, (req) => enc.mark(req, m), T.ACK, opts); }
  /* commander: replaces the shared selection; resolves the ACK ({ count: connections it went to }) */
  select(ids, opts) { return this.call(T.SELECT, (req) => enc.select(req, ids), T.ACK, opts); }
  /* commander: resolves DESTROYED */
  destroy(m, opts) { return this.call(T.DESTROY, (req) => enc.destroy(req, m), T.DESTROYED, opts); }
  envGet(opts) { return this.call(T.ENV_GET, (req) => enc.empty(T.ENV_GET, req), T.ENV_REPLY, opts); }
  /* one frame: resolves the FRAME (data views the received bytes) */
  render(m, opts) { return this.call(T.RENDER, (req) => enc.render(req, m), T.FRAME, opts); }
  /* starts or re-aims the stream; resolves { ack, req }: the stream's
   * FRAMEs carry req (and m.viewSeq) and go to onframe */
  async frameSubscribe(m, opts) {
    let sreq = 0;
    const ack = await this.call(T.FRAME_SUBSCRIBE, (req) => enc.frameSubscribe((sreq = req), m), T.ACK, opts);
    return { ack, req: sreq };
  }
  frameUnsubscribe(opts) {
    return this.call(T.FRAME_UNSUBSCRIBE, (req) => enc.empty(T.FRAME_UNSUBSCRIBE, req), T.ACK, opts);
  }

  /* Sends the frame make(req) builds (type names it in messages) and
   * resolves with the decoded reply of type replyType, or rejects. The path
   * for messages without a method: client.call(T.X, (req) => enc.raw(T.X,
   * req, bytes), T.Y); replyType null resolves the frame { type, req,
   * payload } undecoded. */
  call(type, make, replyType, { timeoutMs = this.timeoutMs } = {}) {
    return new Promise((resolve, reject) => {
      if (this.closed) return reject(new VpError('CLOSED', `${typeName(type)}: the connection is closed`));
      const req = this.takeReq();
      let bytes;
      try {
        bytes = make(req);
      } catch (e) {
        return reject(e);
      }
      const len = bytes.length - VP_HEADER_SIZE;
      if (len > this.serverMaxPayload)
        return reject(new VpError('TOO_LARGE', `${typeName(type)} of ${len} bytes is over the server's limit of ${this.serverMaxPayload} (not sent: the server would close the connection)`));
      const timer = timeoutMs > 0 ? setTimeout(() => {
        this.pending.delete(req);
        reject(new VpError('TIMEOUT', `no reply to ${typeName(type)} (req ${req}) in ${timeoutMs} ms`, { req }));
      }, timeoutMs) : null;
      this.pending.set(req, { type, replyType, resolve, reject, timer });
      try {
        this.t.send(bytes);
      } catch (e) {
        this.settle(req, null, new VpError('CLOSED', `${typeName(type)}: send failed: ${e.message}`, { req }));
      }
    });
  }

  takeReq() {
    const r = this.nextReq;
    this.nextReq = r >= 0xffffffff ? 1 : r + 1; // 0 is the pushes' req
    return r;
  }

  close() {
    if (!this.closed) this.t.close();
  }

  settle(req, value, err) {
    const p = this.pending.get(req);
    if (!p) return false;
    this.pending.delete(req);
    if (p.timer) clearTimeout(p.timer);
    if (err) p.reject(err);
    else p.resolve(value);
    return true;
  }

  bytes(chunk) {
    if (this.closed) return; // bytes a transport delivers after the end
    let frames;
    try {
      frames = this.parser.push(chunk);
    } catch (e) {
      for (const f of e.frames ?? []) this.frame(f);
      this.emit('onerror', e);
      this.ended({ reason: e.message, error: e });
      this.t.close();
      return;
    }
    for (const f of frames) this.frame(f);
  }

  frame(f) {
    const p = f.req ? this.pending.get(f.req) : null;
    if (p && (f.type === T.ERROR || p.replyType === null || f.type === p.replyType)) {
      let v, err = null;
      try {
        if (f.type === T.ERROR) {
          const e = decError(f.payload);
          err = new VpError(e.codeName, e.msg, { index: e.index, local: false, req: f.req, code: e.code });
        } else v = p.replyType === null ? f : decode(f.type, f.payload);
      } catch (e) {
        err = e;
      }
      this.settle(f.req, v, err);
      return;
    }
    if (p && f.type !== T.FRAME) { // a reply of the wrong type
      this.settle(f.req, null, new VpError('TYPE', `${typeName(f.type)} answered ${typeName(p.type)} (req ${f.req}); expected ${typeName(p.replyType)}`, { req: f.req }));
      return;
    }
    try {
      switch (f.type) {
      case T.EVENT: return this.emit('onevent', decode(T.EVENT, f.payload));
      case T.MARKED: return this.emit('onmarked', decode(T.MARKED, f.payload));
      case T.SELECTED: return this.emit('onselected', decode(T.SELECTED, f.payload));
      case T.FRAME: return this.emit('onframe', decode(T.FRAME, f.payload), f.req);
      case T.ERROR: {
        const e = decError(f.payload);
        return this.emit('onerror', new VpError(e.codeName, e.msg, { index: e.index, local: false, req: f.req, code: e.code }));
      }
      default:
        return this.emit('onerror', new VpError('TYPE', `unexpected ${typeName(f.type)} (req ${f.req})`, { req: f.req }));
      }
    } catch (e) {
      this.emit('onerror', e);
    }
  }

  emit(name, ...args) {
    const cb = this[name];
    if (!cb) return;
    try {
      cb(...args);
    } catch (e) {
      this.callbackFailed(e);
    }
  }

  /* A callback's exception: rethrown from a microtask, so the console (or
   * Node's uncaughtException) reports it and the stream goes on. */
  callbackFailed(e) {
    queueMicrotask(() => { throw e; });
  }

  ended(info = {}) {
    if (this.closed) return;
    this.closed = true;
    for (const req of [...this.pending.keys()])
      this.settle(req, null, new VpError('CLOSED', `the connection closed before the reply${info.reason ? ` (${info.reason})` : ''}`, { req }));
    this.emit('onclose', info);
  }
}

// ---- the browser's transport ------------------------------------------------------------

/*
 * A WebSocket as a Client transport: resolves once open. Binary messages
 * are bytes of the stream (binaryType arraybuffer: a view, no copy); a text
 * message is not part of the protocol and closes the socket (1003).
 * WebSocketImpl defaults to the global WebSocket (tests may pass another).
 */
export function wsTransport(url, { WebSocketImpl = globalThis.WebSocket } = {}) {
  return new Promise((resolve, reject) => {
    if (!WebSocketImpl) return reject(new VpError('UNSUPPORTED', 'no WebSocket in this environment'));
    const ws = new WebSocketImpl(url);
    ws.binaryType = 'arraybuffer';
    let open = false;
    const t = {
      ws,
      onbytes: null,
      onclose: null,
      send(b) { ws.send(b); },
      close() { ws.close(1000); },
    };
    ws.onopen = () => {
      open = true;
      resolve(t);
    };
    ws.onmessage = (ev) => {
      if (typeof ev.data === 'string') {
        ws.close(1003, 'text messages are not part of the protocol');
        return;
      }
      if (t.onbytes) t.onbytes(new Uint8Array(ev.data));
    };
    ws.onclose = (ev) => {
      if (!open) reject(new VpError('CLOSED', `WebSocket ${url} closed before it opened (code ${ev.code})`));
      else if (t.onclose) t.onclose({ code: ev.code, reason: ev.reason });
    };
    ws.onerror = () => {}; // onclose follows with the code
  });
}
