/*
 * cmdr.js — the commander's rules in the browser: client/commander/pad_map.c
 * (the mapping, dead zones, response curve, trigger hysteresis, config file,
 * fixed-tick camera and actions, views, picking, latency rings) compiled to
 * WebAssembly (cmdr.wasm, from cmdr_wasm.c, `make all`), wrapped in a class,
 * and the browser's inputs as the C pad state: the Gamepad API's "standard"
 * layout by the table below, the keyboard by the C's own key table. One ES module, no dependencies; the pages import it,
 * and Node 20 imports the same file (tests/cmdr_wasm.mjs).
 *
 *   import { Commander } from './js/cmdr.js';
 *   const cmdr = await Commander.create(configText);    // throws the C parser's error text
 *   // every 1 / cmdr.tickHz s:
 *   const pad = cmdr.padFromGamepad(navigator.getGamepads()[0]) ?? cmdr.padFromKeys(heldCodes);
 *   const { moved, fired, actions } = cmdr.step(pad);
 *   if (moved) subscribe(cmdr.view(1280, 720));          // 160 bytes, the protocol's vp_view
 *
 * One Commander is one WebAssembly instance (the C keeps its state in
 * statics): 0.25 MiB of memory each. Loading: fetch in a browser
 * (compiled from the bytes, so the server's Content-Type does not matter),
 * fs in Node. The module's WASI imports (fd_write, fd_seek, fd_close) come
 * from wasi-libc's stdio: its printf and strtod reach stderr only to report
 * a long double they were built without, and the C formats no long double
 * and calls no strtold, so they are never called; the stubs throw if they
 * ever are, rather than hide it.
 */

const WASM_URL = new URL('./cmdr.wasm', import.meta.url);
const MOVED = 0x80000000; // cmdr_w_step: the camera changed (CMDR_W_MOVED)
const VIEW_SIZE = 160; // VP_VIEW_SIZE

const modules = new Map(); // url -> Promise<WebAssembly.Module>

async function readBytes(url) {
  if (url.protocol === 'file:' && typeof process !== 'undefined' && process.versions?.node) {
    const { readFile } = await import('node:fs/promises');
    return readFile(url);
  }
  const res = await fetch(url);
  if (!res.ok) throw new Error(`cmdr.js: ${url}: HTTP ${res.status}`);
  return res.arrayBuffer();
}

/* The compiled module (once per URL). */
export function loadModule(url = WASM_URL) {
  const u = new URL(url, WASM_URL);
  if (!modules.has(u.href)) {
    const p = readBytes(u).then((b) => WebAssembly.compile(b));
    p.catch(() => modules.delete(u.href)); // a failed load may be retried
    modules.set(u.href, p);
  }
  return modules.get(u.href);
}

function importsFor(mod) {
  const wasi = {};
  for (const i of WebAssembly.Module.imports(mod)) {
    if (i.module !== 'wasi_snapshot_preview1' || i.kind !== 'function')
      throw new Error(`cmdr.wasm imports ${i.module}.${i.name}: not a WASI function this page provides`);
    wasi[i.name] = () => {
      throw new Error(`cmdr.wasm called WASI ${i.name}: wasi-libc reached its stdio (a long double?)`);
    };
  }
  return { wasi_snapshot_preview1: wasi };
}

/* ---- the browser's inputs as the C pad state ------------------------------------------------ */

/*
 * The W3C Gamepad "standard" layout (https://w3c.github.io/gamepad/#remapping)
 * onto pad.h's buttons, by position as SDL's game controller and our
 * hidraw/libusb parsers name them: button index -> pad.h name. 6 and 7 are
 * the triggers: their value is lt / rt (the hysteresis in cmdr_step makes
 * them buttons) and pressed their digital bit, as DS4 / DualSense / Switch
 * reports carry. 17 is not in the standard: Chromium gives a DualShock 4's
 * or DualSense's touchpad click there.
 */
export const STANDARD_BUTTONS = Object.freeze([
  'south', 'east', 'west', 'north', 'lshoulder', 'rshoulder', 'ltrigger_d', 'rtrigger_d',
  'back', 'start', 'lstick', 'rstick', 'dpad_up', 'dpad_down', 'dpad_left', 'dpad_right', 'guide', 'touchpad',
]);
/* axes: [index, sign]: the standard's y axes point down, pad.h's up */
export const STANDARD_AXES = Object.freeze({ lx: [0, 1], ly: [1, -1], rx: [2, 1], ry: [3, -1] });
export const STANDARD_TRIGGERS = Object.freeze({ lt: 6, rt: 7 });

function num(v) {
  return typeof v === 'number' && Number.isFinite(v) ? v : 0;
}

/* ---- the class --------------------------------------------------------------------------------- */

export class Commander {
  /* A Commander on its own instance of the module at url (default: next to
   * this file), configured by configText (the config file's text; '' or
   * undefined: the defaults). Rejects with the C parser's error text. */
  static async create(configText = '', { url, aspect } = {}) {
    const mod = await loadModule(url);
    const instance = await WebAssembly.instantiate(mod, importsFor(mod));
    return new Commander(configText, { instance, aspect });
  }

  /* Synchronous, given an instance (Commander.create makes one) or a
   * compiled module (loadModule's; instantiating synchronously on a page's
   * main thread works in Chromium 156 for this 77 KB module, but browsers
   * have limited it for larger ones: prefer create). A page's CSP must
   * allow 'wasm-unsafe-eval' in script-src for either.
   * aspect: the frames' width / height for the camera's reset (16/9). */
  constructor(configText = '', { instance, module, aspect = 16 / 9 } = {}) {
    if (!instance) {
      if (!module) throw new Error('cmdr.js: new Commander needs { instance } or { module }: use Commander.create()');
      instance = new WebAssembly.Instance(module, importsFor(module));
    }
    this.x = instance.exports;
    this.x._initialize?.();
    this.x.cmdr_w_init(aspect);
    this.actionNames = this.#names(this.x.cmdr_w_action_name);
    this.buttonNames = this.#names(this.x.cmdr_w_button_name);
    this.keyCodes = this.#names(this.x.cmdr_w_key_code); // KeyboardEvent.code of the keys padFromKeys reads
    this.buttonBit = Object.fromEntries(this.buttonNames.map((n, i) => [n, 2 ** i]));
    if (configText) {
      const e = this.configure(configText);
      if (e) throw new Error(e);
    }
  }

  #mem() {
    return this.x.memory.buffer; // re-read: a grown memory detaches older views
  }

  #str(ptr) {
    if (!ptr) return null;
    const b = new Uint8Array(this.#mem(), ptr);
    return new TextDecoder().decode(b.subarray(0, b.indexOf(0)));
  }

  #doubles(ptr, n) {
    return ptr ? Array.from(new Float64Array(this.#mem(), ptr, n)) : null;
  }

  #names(fn) {
    const out = [];
    for (let i = 0; ; i++) {
      const s = this.#str(fn(i));
      if (s === null) return Object.freeze(out);
      out.push(s);
    }
  }

  /* Reads a config text (the file `vantage commander --config` reads):
   * null when taken (the settings replaced), else the C parser's error
   * ("line 3: curve: 9 is outside 0.2..5") and nothing changed. */
  configure(text) {
    const bytes = typeof text === 'string' ? new TextEncoder().encode(text) : new Uint8Array(text);
    const max = this.x.cmdr_w_text_max();
    new Uint8Array(this.#mem(), this.x.cmdr_w_text(), max).set(bytes.subarray(0, max));
    return this.x.cmdr_w_parse(bytes.length) ? this.#str(this.x.cmdr_w_error()) : null;
  }

  /* The fixed tick rate (Hz, the config's tick_hz) and an action's buttons (pad.h names). */
  get tickHz() {
    return this.x.cmdr_w_tick_hz();
  }

  binding(action) {
    const a = typeof action === 'string' ? this.actionNames.indexOf(action) : action;
    const bits = a >= 0 ? this.x.cmdr_w_binding(a) : 0;
    return this.buttonNames.filter((_, i) => bits & (2 ** i));
  }

  /* One fixed step of dt seconds (default 1 / tickHz) with pad = { buttons
   * (pad.h bits), lx, ly, rx, ry (-1..1, +y up), lt, rt (0..1) }, or null
   * for nothing held. Returns { moved, fired (1 << action bits), actions
   * (their names) }. */
  step(pad, dt = 1 / this.tickHz) {
    const p = pad ?? {};
    const r = this.x.cmdr_w_step(p.buttons >>> 0 || 0, num(p.lx), num(p.ly), num(p.rx), num(p.ry), num(p.lt), num(p.rt), num(dt));
    const fired = (r & ~MOVED) >>> 0;
    return { moved: (r & MOVED) !== 0, fired, actions: this.actionNames.filter((_, i) => fired & (1 << i)) };
  }

  /* { target: [x, y, z], yaw, pitch, halfH, perspective, aspect } (metres, radians) */
  get camera() {
    const c = this.#doubles(this.x.cmdr_w_camera(), 8);
    return { target: c.slice(0, 3), yaw: c[3], pitch: c[4], halfH: c[5], perspective: c[6] !== 0, aspect: c[7] };
  }

  /* The camera's rules outside a step (commander.c's mouse): */
  reset(aspect = 0) { this.x.cmdr_w_reset(num(aspect)); }
  togglePerspective() { this.x.cmdr_w_toggle_perspective(); }
  wheel(notches) { this.x.cmdr_w_wheel(Math.max(-1e6, Math.min(1e6, Math.trunc(num(notches))))); } // + zooms in
  click(x, y, w, h) { this.x.cmdr_w_click(w >>> 0, h >>> 0, num(x), num(y)); } // pans to pixel (x, y) of w x h

  #view(ptr) {
    return ptr ? new Uint8Array(this.#mem(), ptr, VIEW_SIZE).slice() : null;
  }

  /* The camera as a w x h view: the protocol's 160 view bytes (what
   * FRAME_SUBSCRIBE and VIS_QUERY carry), or null (a size outside 1..4096). */
  view(w, h) { return this.#view(this.x.cmdr_w_view(w >>> 0, h >>> 0)); }
  /* The narrow view around the reticle for a select's VIS_QUERY: size metres across (ortho). */
  pickView(size) { return this.#view(this.x.cmdr_w_pick_view(num(size))); }
  /* The reticle's ray: { eye: [3], dir: [3] (unit) }. */
  ray() {
    const r = this.#doubles(this.x.cmdr_w_ray(), 6);
    return { eye: r.slice(0, 3), dir: r.slice(3) };
  }
  /* World point p -> [x, y] pixels of a w x h frame (y down), or null (behind the eye, not finite). */
  project(p, w, h) { return this.#doubles(this.x.cmdr_w_project(+p[0], +p[1], +p[2], w >>> 0, h >>> 0), 2); }
  /* The ray o + t d against the box lo..hi: the entry t >= 0, or null (a miss, a number not finite). */
  rayBox(o, d, lo, hi) {
    const t = this.x.cmdr_w_ray_box(...[o, d, lo, hi].flatMap((v) => [0, 1, 2].map((i) => +v[i])));
    return t >= 0 ? t : null;
  }

  /* Latency rings (0..7) of the last 4096 samples (ms), nearest-rank percentiles (NaN when empty). */
  latAdd(ring, ms) { this.x.cmdr_w_lat_add(ring >>> 0, +ms); }
  latPct(ring, p) { return this.x.cmdr_w_lat_pct(ring >>> 0, +p); }
  latCount(ring) { return this.x.cmdr_w_lat_count(ring >>> 0); }
  latClear(ring) { this.x.cmdr_w_lat_clear(ring >>> 0); }

  /* A Gamepad (navigator.getGamepads()[i]) as the C pad state, by the
   * standard layout; null for no pad. A pad whose mapping is not
   * "standard" is read by the same indices (the browser did not know
   * it: its buttons may sit elsewhere), and the result says standard: false. */
  padFromGamepad(gp) {
    if (!gp || gp.connected === false) return null;
    const pad = { buttons: 0, lx: 0, ly: 0, rx: 0, ry: 0, lt: 0, rt: 0, standard: gp.mapping === 'standard' };
    const btn = gp.buttons ?? [];
    STANDARD_BUTTONS.forEach((name, i) => {
      const b = btn[i];
      if (b && (b.pressed === true || (typeof b === 'number' && b > 0.5))) pad.buttons |= this.buttonBit[name];
    });
    pad.buttons >>>= 0;
    for (const [k, [i, sign]] of Object.entries(STANDARD_AXES)) pad[k] = sign * num(gp.axes?.[i]);
    for (const [k, i] of Object.entries(STANDARD_TRIGGERS)) pad[k] = num(typeof btn[i] === 'number' ? btn[i] : btn[i]?.value);
    return pad;
  }

  /* Held keys (a Set or array of KeyboardEvent.code) as the C pad state,
   * by pad_map.c's cmdr_key_table (the SDL window's keys: WASD / arrows
   * pan, Q/E rotate, R/F tilt, Z/X or PageDown/PageUp zoom, Space or Enter
   * select, P ping, C cancel, Delete destroy, [ ] groups, Tab perspective,
   * Home reset); null when none of them is held. */
  padFromKeys(codes) {
    const held = codes instanceof Set ? codes : new Set(codes ?? []);
    let down = 0;
    this.keyCodes.forEach((c, i) => { if (held.has(c)) down |= 2 ** i; });
    const v = this.#doubles(this.x.cmdr_w_keys_pad(down >>> 0), 8);
    return v[0] ? { buttons: v[1] >>> 0, lx: v[2], ly: v[3], rx: v[4], ry: v[5], lt: v[6], rt: v[7] } : null;
  }
}

export { MOVED, VIEW_SIZE };
