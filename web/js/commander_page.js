/*
 * commander_page.js — `vantage commander` in the browser (commander.html):
 * the tablet-commander view of the battlefield driven by a game pad (the
 * Gamepad API), or the keyboard and mouse, issuing orders: select, ping
 * (MARK, shown to every commander), destroy.
 *
 * The rules are the SDL client's own C, compiled to WebAssembly
 * (cmdr.wasm, client/commander/pad_map.c via cmdr.js): the mapping, dead
 * zones, response curve, trigger hysteresis, bindings and config file, the
 * fixed-tick camera (top-down orthographic or tilted perspective), the
 * views, the pick view and ray. This file does only what commander.c does
 * around them: polling the inputs every tick, re-aiming the stream when the
 * camera moved, and the select / ping / destroy requests.
 *
 * A config file's text may be given in the page (the same lines as
 * `vantage commander --config FILE`); it is kept in this page only.
 */
import { Commander } from './cmdr.js';
import { Reader, LAYOUTS, getLayout } from './vproto.js';
import { pageOptions, connectAsking, videoFormat, Stream, showStats, ROLE,
         VP_EVENT_SCENE, VP_EVENT_MARKS } from './stream.js';

const $ = (id) => document.getElementById(id);
const canvas = $('stream');
const opts = pageOptions();
const GROUPS = 4; /* CMDR_GROUPS */
const DESTROY_RADIUS = 3; /* commander.c's default --destroy-radius */

let cmdr = null, client = null, stream = null;
let selected = null, group = 0, picking = false;
const held = new Set(); /* KeyboardEvent.code of the keys held */
const marks = []; /* { pos, kind, until (ms), from } */
/* Input times for the latency: the newest input event (a key, the wheel, a
 * click; a game pad's own timestamp of its last change); a view the held
 * input keeps moving counts from the tick that sampled it. */
let lastInput = performance.now(), lastAimed = 0, padName = 'keyboard/mouse';

function say(t) {
  $('status').textContent = t;
}

function frameSize() {
  if (opts.width && opts.height) return [opts.width, opts.height];
  const r = canvas.parentElement.getBoundingClientRect();
  const s = Math.min(1, 1280 / r.width, 720 / r.height);
  return [Math.max(64, Math.round(r.width * s)) & ~1, Math.max(64, Math.round(r.height * s)) & ~1];
}

/* cmdr.wasm's 160 view bytes as vproto.js's view object */
function viewOf(bytes) {
  return bytes ? getLayout(new Reader(bytes), LAYOUTS.view, 'view') : null;
}

function aim(input = lastInput) {
  if (!stream) return;
  const [w, h] = frameSize();
  const v = viewOf(cmdr.view(w, h));
  if (!v) return;
  stream.aim(v, input, { highlight: selected ? [selected.id] : [] }).catch((e) => say(`frames: ${e.message}`));
}

/* ---- orders ------------------------------------------------------------------------------- */

/* commander.c's start_pick: the narrow view around the reticle (1.5 % of
 * the view across, at least 0.5 m) is queried, occlusion included; the
 * candidates' boxes against the reticle's ray: the nearest. */
async function pick() {
  const cam = cmdr.camera;
  const q = viewOf(cmdr.pickView(Math.max(0.5, 0.03 * cam.halfH)));
  const { eye, dir } = cmdr.ray();
  const r = await client.visQuery([q]);
  if (!r.records.length) return null;
  const got = await client.entityGet(r.records.slice(0, 256).map((x) => x.id));
  let best = null, bt = Infinity;
  for (const e of got.entities) {
    const t = cmdr.rayBox(eye, dir, e.aabb.slice(0, 3), e.aabb.slice(3, 6));
    if (t !== null && t < bt) bt = t, best = e;
  }
  return best ? { entity: best, at: [0, 1, 2].map((a) => eye[a] + bt * dir[a]) } : null;
}

async function order(kind) {
  if (!client) return say('not connected');
  if (kind === 'ping') {
    const t = cmdr.camera.target;
    await client.mark({ pos: t, entity: 0n, kind: 0, ttl_ms: 6000 });
    return say(`ping at (${t.map((v) => v.toFixed(1)).join(', ')})`);
  }
  if (picking) return;
  picking = true;
  try {
    const hit = await pick();
    if (!hit) {
      if (kind === 'select') selected = null, aim();
      return say(kind === 'destroy' ? 'nothing under the reticle to destroy' : 'nothing under the reticle');
    }
    const e = hit.entity;
    if (kind === 'destroy') {
      const r = await client.destroy({ id: e.id, center: hit.at, radius: DESTROY_RADIUS });
      return say(`destroyed #${e.id}: ${r.spheres} sphere(s), ${r.debris} debris`);
    }
    selected = e;
    aim();
    const size = [0, 1, 2].map((a) => (e.aabb[a + 3] - e.aabb[a]).toFixed(0)).join(' x ');
    say(`selected #${e.id} (group ${group + 1}), ${size} m`);
    /* a select is a mark of kind 1 for the other commanders */
    await client.mark({ pos: hit.at, entity: e.id, kind: 1, ttl_ms: 4000 });
  } catch (err) {
    say(`${kind}: ${err.codeName ?? ''} ${err.message}`);
  } finally {
    picking = false;
    window.dispatchEvent(new CustomEvent('vantage-order', { detail: kind }));
  }
}

function fire(actions) {
  for (const a of actions) {
    if (a === 'select') order('select');
    else if (a === 'destroy') order('destroy');
    else if (a === 'ping') order('ping');
    else if (a === 'cancel') selected = null, aim(), say('selection dropped');
    else if (a === 'group_prev') group = (group + GROUPS - 1) % GROUPS, say(`group ${group + 1}`);
    else if (a === 'group_next') group = (group + 1) % GROUPS, say(`group ${group + 1}`);
    /* toggle_perspective and reset_view are the camera's: cmdr_step did them */
  }
}

/* ---- the fixed tick ------------------------------------------------------------------------- */

function pollPad() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  for (const gp of pads) {
    const p = gp && cmdr.padFromGamepad(gp);
    if (p) {
      padName = gp.id;
      if (gp.timestamp > lastInput) lastInput = gp.timestamp;
      return p;
    }
  }
  padName = 'keyboard/mouse';
  return cmdr.padFromKeys(held);
}

let acc = 0, prev = performance.now();
function tick(now) {
  if (cmdr) {
    const dt = 1 / cmdr.tickHz;
    acc = Math.min(acc + (now - prev) / 1000, 0.25); /* a hidden tab does not run 100 ticks at once */
    prev = now;
    let moved = false;
    while (acc >= dt) {
      acc -= dt;
      const r = cmdr.step(pollPad(), dt);
      moved ||= r.moved;
      if (r.actions.length) fire(r.actions);
    }
    if (moved) {
      aim(lastInput > lastAimed ? lastInput : now); /* a new input's time, else this tick's */
      lastAimed = Math.max(lastInput, now);
    }
  }
  overlay();
  requestAnimationFrame(tick);
}

/* ---- the overlay ------------------------------------------------------------------------------ */

function overlay() {
  showStats(stream, () => `${cmdr.camera.perspective ? 'tilted' : 'top-down'}  group ${group + 1}  ` +
    `${padName}${selected ? `  selected #${selected.id}` : ''}`);
  /* the marks, listed (the frames draw them as icons too) */
  const now = performance.now();
  while (marks.length && marks[0].until < now) marks.shift();
  const ul = $('marks');
  const text = marks.map((m) => `${m.kind === 0 ? 'ping' : m.kind === 1 ? 'select' : `kind ${m.kind}`} by #${m.from} ` +
    `at ${m.pos.map((v) => v.toFixed(0)).join(',')}`).join('\n');
  if (ul.textContent !== text) ul.textContent = text || '(none)';
}

/* ---- inputs ----------------------------------------------------------------------------------- */

function inputs() {
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' || e.target.tagName === 'TEXTAREA') return;
    if (cmdr?.keyCodes.includes(e.code)) e.preventDefault();
    if (!held.has(e.code)) lastInput = e.timeStamp;
    held.add(e.code);
  });
  window.addEventListener('keyup', (e) => held.delete(e.code));
  window.addEventListener('blur', () => held.clear());
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    lastInput = e.timeStamp;
    cmdr.wheel(e.deltaY < 0 ? 1 : -1);
    aim(e.timeStamp);
  }, { passive: false });
  canvas.addEventListener('click', (e) => { /* pans to the clicked point (commander.c's mouse) */
    const r = canvas.getBoundingClientRect();
    lastInput = e.timeStamp;
    cmdr.click(e.clientX - r.left, e.clientY - r.top, Math.round(r.width), Math.round(r.height));
    aim(e.timeStamp);
  });
  for (const [id, kind] of [['do-select', 'select'], ['do-ping', 'ping'], ['do-destroy', 'destroy']])
    $(id).addEventListener('click', () => order(kind));
  $('do-toggle').addEventListener('click', () => { cmdr.togglePerspective(); aim(performance.now()); });
  $('config-apply').addEventListener('click', () => {
    const err = cmdr.configure($('config').value);
    $('config-msg').textContent = err ?? 'applied';
    renderBindings();
  });
  window.addEventListener('gamepadconnected', (e) => say(`game pad: ${e.gamepad.id}`));
  window.addEventListener('resize', () => aim(performance.now()));
}

function renderBindings() {
  $('bindings').textContent = cmdr.actionNames.map((a) => `${a}: ${cmdr.binding(a).join('+') || '-'}`).join('\n');
}

/* ---- start ------------------------------------------------------------------------------------- */

async function start() {
  client = await connectAsking({ role: ROLE.COMMANDER, name: 'web commander', roleName: 'commander' }, say);
  if (!client) {
    setTimeout(start, 2000);
    return;
  }
  const format = await videoFormat(opts.forceJpeg);
  stream = new Stream(client, canvas, { format, maxFps: opts.maxFps, motion: opts.motion });
  stream.onKeyNeeded = () => aim(performance.now());
  client.onclose = () => {
    say('disconnected: reconnecting');
    stream = null;
    setTimeout(start, 1000);
  };
  client.onerror = (e) => say(`stream: ${e.codeName} ${e.message}`);
  client.onmarked = (m) => {
    marks.push({ pos: m.mark.pos, kind: m.mark.kind, until: performance.now() + m.mark.ttl_ms, from: m.client_id });
    marks.sort((a, b) => a.until - b.until);
  };
  await client.subscribe(VP_EVENT_SCENE | VP_EVENT_MARKS);
  say(`connected as a commander: ${format === 'h264' ? 'H.264 video' : 'JPEG frames'}`);
  aim(performance.now());
}

async function main() {
  const [w, h] = frameSize();
  cmdr = await Commander.create('', { aspect: w / h });
  renderBindings();
  window.vantage = {
    stats: () => (stream ? stream.stats() : null),
    commander: cmdr,
    get camera() { return cmdr.camera; },
    get selected() { return selected ? String(selected.id) : null; },
    get group() { return group; },
    get lastSeq() { return stream ? stream.seq : 0; },
    marks,
    order,
  };
  inputs();
  requestAnimationFrame(tick);
  await start();
}

main().catch((e) => say(`commander: ${e.message}`));
