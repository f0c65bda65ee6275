/*
 * commander.test.mjs — the commander page (web/commander.html) in headless
 * Chromium: a faked game pad (navigator.getGamepads replaced before the
 * page's scripts run: Chromium has no gamepad emulation) pans the view and
 * the frames follow it; select, ping (MARK) and destroy from the pad's
 * buttons, seen by another commander client and by the CLI.
 */
import test from 'node:test';
import assert from 'node:assert/strict';
import { existsSync } from 'node:fs';
import { skipReason, webDaemonAndBrowser } from './chromium.mjs';
import { cli, connect, jsonLines, TOKENS } from './harness.mjs';
import { ROLE, VP_EVENT_MARKS } from '../../web/js/vproto.js';

const skip = skipReason || (!existsSync(new URL('../../web/js/cmdr.wasm', import.meta.url)) ? 'web/js/cmdr.wasm is not built (make all)' : false);

/* A standard-mapping pad the test moves: window.__pad.set({ buttons: {0: 1}, axes: {0: 0.8} }). */
const PAD_SHIM = () => {
  const mk = () => ({ id: 'Test Pad (STANDARD GAMEPAD)', index: 0, connected: true, mapping: 'standard',
    timestamp: performance.now(), axes: [0, 0, 0, 0],
    buttons: Array.from({ length: 17 }, () => ({ pressed: false, touched: false, value: 0 })) });
  let pad = null;
  Object.defineProperty(Navigator.prototype, 'getGamepads', { configurable: true, value: () => [pad, null, null, null] });
  window.__pad = {
    connect() { pad = mk(); },
    set({ buttons = {}, axes = {} }) {
      for (const [k, v] of Object.entries(buttons)) pad.buttons[k] = { pressed: v > 0.5, touched: v > 0, value: +v };
      for (const [k, v] of Object.entries(axes)) pad.axes[k] = v;
      pad.timestamp = performance.now();
    },
  };
};

let d, browser, env;
test.before(async () => {
  if (skip) return;
  /* one big box under the reticle (the camera starts over the origin), others around */
  env = await webDaemonAndBrowser([[1, '0,3,0', 4], [2, '30,2,10', 3], [3, '-25,2,-20', 3]]);
  ({ d, browser } = env);
});
test.after(async () => {
  await env?.stop();
});

async function open() {
  const page = await browser.newPage();
  await page.setViewport({ width: 900, height: 520 });
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  await page.evaluateOnNewDocument(PAD_SHIM);
  await page.goto(`http://127.0.0.1:${d.webPort}/commander.html?size=320x180#token=${TOKENS.commander}`);
  await page.waitForFunction(() => window.vantage?.stats()?.last, { timeout: 10000 });
  await page.evaluate(() => window.__pad.connect());
  return { page, errors };
}

const stats = (page) => page.evaluate(() => window.vantage.stats());
const camera = (page) => page.evaluate(() => window.vantage.camera);

/* Presses a pad button for a few ticks, then lets go (the fixed tick samples it). */
async function press(page, button) {
  await page.evaluate((b) => window.__pad.set({ buttons: { [b]: 1 } }), button);
  await new Promise((r) => setTimeout(r, 120));
  await page.evaluate((b) => window.__pad.set({ buttons: { [b]: 0 } }), button);
}

test('a faked game pad pans the view; the next frames carry its view_seq and follow the camera', { skip }, async (t) => {
  const { page, errors } = await open();
  const before = await stats(page), cam0 = await camera(page);
  /* the left stick full right for 0.6 s: past the dead zone, the camera pans */
  await page.evaluate(() => window.__pad.set({ axes: { 0: 1 } }));
  await new Promise((r) => setTimeout(r, 600));
  await page.evaluate(() => window.__pad.set({ axes: { 0: 0 } }));
  const cam1 = await camera(page);
  const moved = Math.hypot(cam1.target[0] - cam0.target[0], cam1.target[2] - cam0.target[2]);
  assert.ok(moved > 1, `the stick moved the camera ${moved.toFixed(2)} m`);
  assert.equal(cam1.target[1], cam0.target[1], 'a pan stays on the ground plane');
  /* the frames follow: a frame of the last view the page sent arrives */
  let last;
  for (let i = 0; i < 100; i++) {
    last = await stats(page);
    const sent = await page.evaluate(() => window.vantage.lastSeq);
    if (last.last.view_seq === sent) break;
    await new Promise((r) => setTimeout(r, 50));
  }
  assert.ok(last.last.view_seq > before.last.view_seq, `view_seq ${before.last.view_seq} -> ${last.last.view_seq}`);
  assert.equal(last.last.view_seq, await page.evaluate(() => window.vantage.lastSeq), 'the last view sent is drawn');
  assert.ok(last.samples > 0, 'input-to-photon was measured');
  t.diagnostic(`pad pan: ${moved.toFixed(1)} m, ${last.samples} latency samples, p50 ${last.p50?.toFixed(1)} ms`);
  /* a stick inside the dead zone moves nothing */
  const cam2 = await camera(page);
  await page.evaluate(() => window.__pad.set({ axes: { 0: 0.1, 1: -0.1 } }));
  await new Promise((r) => setTimeout(r, 300));
  await page.evaluate(() => window.__pad.set({ axes: { 0: 0, 1: 0 } }));
  assert.deepEqual((await camera(page)).target, cam2.target, 'inside the dead zone (0.15) nothing moves');
  assert.deepEqual(errors, []);
  await page.close();
});

test('select, ping (MARK to every commander) and destroy from the pad', { skip }, async () => {
  const { page, errors } = await open();
  /* back over the box */
  await press(page, 11); /* right stick press: reset_view */
  const other = await connect(d, ROLE.COMMANDER);
  await other.subscribe(VP_EVENT_MARKS);
  const marked = [];
  other.onmarked = (m) => marked.push(m);
  /* select: south (button 0) */
  await press(page, 0);
  await page.waitForFunction(() => window.vantage.selected !== null, { timeout: 5000 });
  assert.equal(await page.evaluate(() => window.vantage.selected), '1');
  /* ping: west (button 2) */
  await press(page, 2);
  for (let i = 0; i < 100 && !marked.some((m) => m.mark.kind === 0); i++) await new Promise((r) => setTimeout(r, 50));
  const ping = marked.find((m) => m.mark.kind === 0);
  assert.ok(ping, `the other commander got the ping: ${JSON.stringify(marked.map((m) => m.mark.kind))}`);
  assert.ok(marked.some((m) => m.mark.kind === 1 && m.mark.entity === 1n), 'and the select, a mark of kind 1 on entity 1');
  /* the page lists the marks it got (its own included) */
  await page.waitForFunction(() => window.vantage.marks.length >= 1, { timeout: 5000 });
  /* destroy: north (button 3) */
  await press(page, 3);
  await page.waitForFunction(() => /destroyed #1/.test(document.getElementById('status').textContent), { timeout: 5000 });
  /* the CLI's own DESTROY of entity 1 finds the page's sphere in its set */
  const r = await cli(d, ['destroy', '1', '0,3,0', '0.5', '--json']);
  assert.equal(r.code, 0, r.stderr);
  assert.equal(jsonLines(r.stdout)[0].spheres, 2);
  other.close();
  assert.deepEqual(errors, []);
  await page.close();
});
