/*
 * viewer.js — the browser viewer (index.html): the daemon's frames of a
 * camera of one's own, orbited, panned and zoomed by mouse or touch; a
 * stats overlay; the sub-levels and the count of entities a visibility
 * query of the same view finds; a click selects the entity under it
 * (outlined in the frames) and shows its fields.
 *
 * Controls: left drag orbits, right drag (or shift + drag) pans, the wheel
 * zooms; one finger orbits, two pinch-zoom and pan. A double click re-aims
 * the orbit at the clicked entity.
 */
import { viewPerspective, VP_Q_COUNT_ONLY, VP_EVENT_SCENE } from './vproto.js';
import { pageOptions, connectAsking, videoFormat, Stream, showStats, ROLE } from './stream.js';

const $ = (id) => document.getElementById(id);
const canvas = $('stream');
const opts = pageOptions();

/* the orbit: around target, yaw and pitch in radians, dist metres */
const cam = { target: [0, 0, 0], yaw: Math.PI / 4, pitch: 0.75, dist: 300, fov: 60 };
let client = null, stream = null, selected = null, visTimer = 0, lastView = null;
if (opts.eye && opts.at) { /* ?eye=&at=: the orbit that puts the camera there */
  const d = [opts.eye[0] - opts.at[0], opts.eye[1] - opts.at[1], opts.eye[2] - opts.at[2]];
  cam.target = opts.at;
  cam.dist = Math.max(1e-3, Math.hypot(...d));
  cam.pitch = Math.asin(Math.max(-1, Math.min(1, d[1] / cam.dist)));
  cam.yaw = Math.atan2(d[0], d[2]);
}

function frameSize() {
  if (opts.width && opts.height) return [opts.width, opts.height];
  const r = canvas.parentElement.getBoundingClientRect();
  const dpr = Math.min(window.devicePixelRatio || 1, 2);
  let w = Math.round(r.width * dpr), h = Math.round(r.height * dpr);
  const s = Math.min(1, 1280 / w, 720 / h); /* at most 1280x720: the daemon's budget */
  w = Math.max(64, Math.round(w * s)) & ~1;
  h = Math.max(64, Math.round(h * s)) & ~1;
  return [w, h];
}

function eye() {
  const c = Math.cos(cam.pitch);
  return [cam.target[0] + cam.dist * c * Math.sin(cam.yaw), cam.target[1] + cam.dist * Math.sin(cam.pitch),
          cam.target[2] + cam.dist * c * Math.cos(cam.yaw)];
}

function view(w, h) {
  return viewPerspective({ eye: eye(), target: cam.target, fovDeg: cam.fov, width: w, height: h, near: 0.5, far: 20000 });
}

/* A camera change: the stream re-aimed at once (input time = the event's) */
function aim(inputTime = performance.now()) {
  if (!stream) return;
  const [w, h] = frameSize();
  const v = view(w, h);
  if (!v) return;
  lastView = v;
  stream.aim(v, inputTime, { highlight: selected ? [selected.id] : [] }).catch((e) => status(`frames: ${e.message}`));
  clearTimeout(visTimer);
  visTimer = setTimeout(countVisible, 120);
}

async function countVisible() {
  if (!client || !lastView) return;
  try {
    const r = await client.visQuery([lastView], { flags: VP_Q_COUNT_ONLY });
    $('visible').textContent = `${r.visible} of ${r.tested} entities visible (culling query of this view)`;
  } catch (e) {
    $('visible').textContent = `visibility query: ${e.message}`;
  }
}

async function listSublevels() {
  try {
    const r = await client.sublevelInfo();
    const ul = $('sublevels');
    ul.replaceChildren(...r.sublevels.map((s) => {
      const li = document.createElement('li');
      li.textContent = `${s.name}: ${s.stateName}, ${s.entities} entities`;
      return li;
    }));
    if (!r.sublevels.length) ul.replaceChildren(Object.assign(document.createElement('li'), { textContent: '(none)' }));
  } catch (e) {
    $('sublevels').textContent = e.message;
  }
}

function status(t) {
  $('status').textContent = t;
}

/* ---- picking ------------------------------------------------------------------------ */

function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
function add(a, b) { return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]; }
function mul(a, s) { return [a[0] * s, a[1] * s, a[2] * s]; }
function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
function norm(a) { const l = Math.hypot(...a); return mul(a, 1 / l); }

/* The ray through canvas pixel (px, py) (CSS pixels of the canvas box). */
function rayAt(px, py) {
  const r = canvas.getBoundingClientRect();
  const e = eye(), f = norm(sub(cam.target, e)), right = norm(cross(f, [0, 1, 0])), up = cross(right, f);
  const th = Math.tan((cam.fov * Math.PI) / 360), aspect = canvas.width / canvas.height;
  const x = ((px / r.width) * 2 - 1) * th * aspect, y = (1 - (py / r.height) * 2) * th;
  return { o: e, d: norm(add(f, add(mul(right, x), mul(up, y)))) };
}

/* Slab test: the ray's entry t into the box, or Infinity. */
function rayBox(o, d, lo, hi) {
  let t0 = 0, t1 = Infinity;
  for (let a = 0; a < 3; a++) {
    const inv = 1 / d[a];
    let ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
    if (ta > tb) [ta, tb] = [tb, ta];
    t0 = Math.max(t0, ta);
    t1 = Math.min(t1, tb);
    if (t0 > t1) return Infinity;
  }
  return t0;
}

/* A narrow visibility query along the ray (the same culling, occlusion
 * included), then the candidates' boxes against the ray: the nearest. */
async function pick(px, py) {
  const { o, d } = rayAt(px, py);
  const v = viewPerspective({ eye: o, target: add(o, d), fovDeg: 1, width: 64, height: 64, near: 0.5, far: 20000 });
  if (!v) return null;
  const r = await client.visQuery([v]);
  const ids = r.records.slice(0, 256).map((x) => x.id);
  if (!ids.length) return null;
  const got = await client.entityGet(ids);
  let best = null, bt = Infinity;
  for (const e of got.entities) {
    const t = rayBox(o, d, e.aabb.slice(0, 3), e.aabb.slice(3, 6));
    if (t < bt) bt = t, best = e;
  }
  return best ? { entity: best, t: bt, point: add(o, mul(d, bt)) } : null;
}

function showEntity(e) {
  const dl = $('entity');
  if (!e) {
    dl.replaceChildren();
    $('selection').textContent = 'nothing selected';
    return;
  }
  $('selection').textContent = `entity ${e.id}`;
  const f = (a) => Array.from(a, (v) => Number(v).toFixed(2)).join(', ');
  const rows = [['id', String(e.id)], ['class', e.class_id], ['sub-level', e.sublevel], ['flags', `0x${e.flags.toString(16)}`],
    ['material', e.material], ['position', f(e.pos)], ['scale', f(e.scale)], ['box min', f(e.aabb.slice(0, 3))],
    ['box max', f(e.aabb.slice(3, 6))]];
  dl.replaceChildren(...rows.flatMap(([k, v]) => [Object.assign(document.createElement('dt'), { textContent: k }),
    Object.assign(document.createElement('dd'), { textContent: String(v) })]));
}

async function select(px, py, recentre) {
  try {
    const hit = await pick(px, py);
    selected = hit ? hit.entity : null;
    showEntity(selected);
    if (hit && recentre) {
      const b = hit.entity.aabb;
      cam.target = [(b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2];
    }
    aim();
    window.dispatchEvent(new CustomEvent('vantage-selected', { detail: selected ? String(selected.id) : null }));
  } catch (e) {
    status(`select: ${e.message}`);
  }
}

/* ---- controls ------------------------------------------------------------------------- */

/* Pointer moves as they happen: Chromium's pointerrawupdate (a secure
 * context) is dispatched at once, where pointermove waits for the next
 * animation frame (up to 16 ms of input-to-photon); elsewhere pointermove.
 * (Touch pinches keep pointermove: fingers come as pairs of moves.) */
const MOVE = 'onpointerrawupdate' in window ? 'pointerrawupdate' : 'pointermove';

function controls() {
  let drag = null;
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointerdown', (e) => {
    canvas.setPointerCapture(e.pointerId);
    drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey, moved: 0, id: e.pointerId };
  });
  canvas.addEventListener(MOVE, (e) => {
    if (!drag || e.pointerId !== drag.id || touches.size > 1) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    drag.moved += Math.abs(dx) + Math.abs(dy);
    if (drag.pan) pan(dx, dy);
    else {
      cam.yaw -= dx * 0.005;
      cam.pitch = Math.min(1.5, Math.max(0.05, cam.pitch + dy * 0.005));
    }
    aim(e.timeStamp);
  });
  canvas.addEventListener('pointerup', (e) => {
    if (drag && drag.moved < 4 && e.button === 0) {
      const r = canvas.getBoundingClientRect();
      select(e.clientX - r.left, e.clientY - r.top, false);
    }
    drag = null;
  });
  canvas.addEventListener('dblclick', (e) => {
    const r = canvas.getBoundingClientRect();
    select(e.clientX - r.left, e.clientY - r.top, true);
  });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    cam.dist = Math.min(5000, Math.max(2, cam.dist * Math.exp(e.deltaY * 0.001)));
    aim(e.timeStamp);
  }, { passive: false });
  /* touch: two fingers pinch and pan */
  const touches = new Map();
  let pinch = null;
  canvas.addEventListener('pointerdown', (e) => { if (e.pointerType === 'touch') touches.set(e.pointerId, [e.clientX, e.clientY]); });
  canvas.addEventListener('pointerup', (e) => { touches.delete(e.pointerId); pinch = null; });
  canvas.addEventListener('pointercancel', (e) => { touches.delete(e.pointerId); pinch = null; drag = null; });
  canvas.addEventListener('pointermove', (e) => {
    if (!touches.has(e.pointerId)) return;
    touches.set(e.pointerId, [e.clientX, e.clientY]);
    if (touches.size !== 2) return;
    const [a, b] = [...touches.values()];
    const d = Math.hypot(a[0] - b[0], a[1] - b[1]), c = [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2];
    if (pinch) {
      cam.dist = Math.min(5000, Math.max(2, cam.dist * (pinch.d / d)));
      pan(c[0] - pinch.c[0], c[1] - pinch.c[1]);
      aim(e.timeStamp);
    }
    pinch = { d, c };
  });
  window.addEventListener('resize', () => aim());
}

/* Moves the target across the screen plane by (dx, dy) CSS pixels. */
function pan(dx, dy) {
  const e = eye(), f = norm(sub(cam.target, e)), right = norm(cross(f, [0, 1, 0])), up = cross(right, f);
  const s = (2 * cam.dist * Math.tan((cam.fov * Math.PI) / 360)) / canvas.getBoundingClientRect().height;
  cam.target = add(cam.target, add(mul(right, -dx * s), mul(up, dy * s)));
}

/* ---- start -------------------------------------------------------------------------------- */

function overlay() {
  showStats(stream, (s) => (s.last ? `epoch ${s.last.epoch}  view ${s.last.view_seq}  ${s.last.width}x${s.last.height}  ` +
    `${s.last.visible} drawn` : 'waiting for the first frame'));
  requestAnimationFrame(overlay);
}

async function start() {
  client = await connectAsking({ role: ROLE.VIEWER, name: 'web viewer', roleName: 'viewer' }, status);
  if (!client) {
    setTimeout(start, 2000);
    return;
  }
  const format = await videoFormat(opts.forceJpeg);
  status(`connected: ${format === 'h264' ? 'H.264 video (WebCodecs)' : 'JPEG frames'}`);
  stream = new Stream(client, canvas, { format, maxFps: opts.maxFps, motion: opts.motion });
  stream.onKeyNeeded = () => aim(); /* a re-aim after the decoder's reset; the daemon keys a new chain */
  client.onclose = () => {
    status('disconnected: reconnecting');
    stream = null;
    setTimeout(start, 1000);
  };
  client.onerror = (e) => status(`stream: ${e.codeName} ${e.message}`);
  client.onevent = () => listSublevels();
  await client.subscribe(VP_EVENT_SCENE);
  listSublevels();
  aim();
}

window.vantage = {
  stats: () => (stream ? stream.stats() : null),
  camera: cam,
  eye,
  near: 0.5,
  far: 20000,
  aim,
  select: (x, y) => select(x, y, false),
  get selected() { return selected ? String(selected.id) : null; },
};
controls();
requestAnimationFrame(overlay);
start();
