/*
 * browser.test.mjs — the pages in headless Chromium (Debian's
 * /usr/bin/chromium, driven by puppeteer-core pinned in package.json; no
 * browser is downloaded): the viewer against a real vantaged --web.
 *
 * The independent model of a frame is the CLI's: `vantage render -o x.png`
 * asks the daemon for the RAW float frame of the same camera and tone-maps
 * it on its own side; the page's canvas (JPEG or H.264 decoded by the
 * browser) must match it within a mean absolute error per channel.
 */
import test from 'node:test';
import assert from 'node:assert/strict';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import { skipReason, webDaemonAndBrowser, launch } from './chromium.mjs';
import { startDaemon, cli, TOKENS } from './harness.mjs';

const skip = skipReason;

let d, browser, tmp, env;
test.before(async () => {
  if (skip) return;
  tmp = mkdtempSync(path.join(os.tmpdir(), 'vantage-browser-'));
  /* a row of boxes of three sizes in front of the first camera, on the ground */
  env = await webDaemonAndBrowser([[1, '0,2,0', 2], [2, '-6,1.5,-4', 1.5], [3, '7,3,2', 3], [4, '0,1,-12', 1]]);
  ({ d, browser } = env);
});
test.after(async () => {
  await env?.stop();
  if (tmp) rmSync(tmp, { recursive: true, force: true });
});

const W = 320, H = 180;
const EYE = '14,9,22', AT = '0,1,0';

/* A page of the viewer with the query string q; console errors fail the test. */
async function open(q, { token = TOKENS.viewer, before = null } = {}) {
  const page = await browser.newPage();
  await page.setViewport({ width: 900, height: 520 });
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  if (before) await page.evaluateOnNewDocument(before);
  const t0 = Date.now();
  await page.goto(`http://127.0.0.1:${d.webPort}/?size=${W}x${H}&eye=${EYE}&at=${AT}&${q}#token=${token}`);
  return { page, errors, t0 };
}

/* Waits until the page has drawn a frame satisfying pred (its stats' last). */
async function drawn(page, pred = () => true, ms = 5000) {
  const t0 = Date.now();
  for (;;) {
    const s = await page.evaluate(() => window.vantage?.stats());
    if (s?.last && pred(s)) return s;
    if (Date.now() - t0 > ms) throw new Error(`no frame drawn in ${ms} ms: ${JSON.stringify(s)}`);
    await new Promise((r) => setTimeout(r, 25));
  }
}

/* The CLI's picture of the page's camera, as a PNG's bytes. */
async function reference(page) {
  const cam = await page.evaluate(() => ({ eye: window.vantage.eye(), at: window.vantage.camera.target,
    fov: window.vantage.camera.fov, near: window.vantage.near, far: window.vantage.far }));
  const out = path.join(tmp, `ref-${Date.now()}.png`);
  const r = await cli(d, ['render', '--eye', cam.eye.join(','), '--at', cam.at.join(','), '--fov', String(cam.fov),
    '--near', String(cam.near), '--far', String(cam.far), '--size', `${W}x${H}`, '-o', out], { token: TOKENS.viewer });
  assert.equal(r.code, 0, r.stderr);
  return readFileSync(out);
}

/* Mean absolute error per channel (RGB, 0..255) of the page's canvas
 * against the PNG, and the share of pixels off by more than 24. */
function compare(page, png) {
  return page.evaluate(async (b64, w, h) => {
    const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
    const bmp = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
    const ref = new OffscreenCanvas(w, h).getContext('2d');
    ref.drawImage(bmp, 0, 0);
    const a = ref.getImageData(0, 0, w, h).data;
    const b = document.getElementById('stream').getContext('2d').getImageData(0, 0, w, h).data;
    let sum = 0, far = 0;
    for (let i = 0; i < a.length; i += 4) {
      let px = 0;
      for (let c = 0; c < 3; c++) {
        const e = Math.abs(a[i + c] - b[i + c]);
        sum += e;
        px = Math.max(px, e);
      }
      far += px > 24;
    }
    return { mae: sum / (w * h * 3), far: far / (w * h) };
  }, png.toString('base64'), W, H);
}

test('the viewer draws its first JPEG frame within 2 s, matching the daemon\'s raw frame', { skip }, async (t) => {
  const { page, errors, t0 } = await open('format=jpeg');
  const s = await drawn(page, () => true, 5000);
  const ms = Date.now() - t0;
  assert.equal(s.format, 'jpeg');
  assert.equal(s.last.width, W);
  assert.ok(ms < 2000, `the first frame took ${ms} ms`);
  const c = await compare(page, await reference(page));
  t.diagnostic(`first frame ${ms} ms after navigation; JPEG against the raw frame: MAE ${c.mae.toFixed(2)}, ` +
    `${(c.far * 100).toFixed(2)} % off by > 24`);
  /* JPEG q80 of a smooth render: a mean error of 1-2 codes; 4 leaves room
     for the 4:2:0 chroma at box edges, not for a wrong view (a camera off
     by one degree gives > 10) */
  assert.ok(c.mae < 4, `mean absolute error ${c.mae.toFixed(2)}`);
  assert.ok(c.far < 0.02, `${(c.far * 100).toFixed(1)} % of the pixels off by more than 24`);
  assert.deepEqual(errors, []);
  await page.close();
});

test('H.264 through WebCodecs: the first frame is a key frame, drawn within 2 s, matching the raw frame', { skip }, async (t) => {
  const { page, errors, t0 } = await open('');
  const s = await drawn(page, () => true, 5000);
  const ms = Date.now() - t0;
  assert.equal(s.format, 'h264', 'headless Chromium on localhost decodes H.264 (a secure context)');
  assert.equal(s.key_waits, 0, 'the stream starts with a key frame');
  assert.ok(ms < 2000, `the first frame took ${ms} ms`);
  const c = await compare(page, await reference(page));
  t.diagnostic(`first H.264 frame ${ms} ms after navigation; against the raw frame: MAE ${c.mae.toFixed(2)}, ` +
    `${(c.far * 100).toFixed(2)} % off by > 24`);
  /* CRF 23 of a smooth render: ~37-45 dB, a mean error of 1-2 codes; the
     browser's own YUV -> RGB moves saturated colours by up to 12 codes
     (measured on patches), so 5 */
  assert.ok(c.mae < 5, `mean absolute error ${c.mae.toFixed(2)}`);
  assert.ok(c.far < 0.03, `${(c.far * 100).toFixed(1)} % of the pixels off by more than 24`);
  assert.deepEqual(errors, []);
  await page.close();
});

test('an edit by another client shows in the next frames', { skip }, async () => {
  const { page } = await open('format=jpeg');
  const first = await drawn(page);
  const a = await cli(d, ['add', '9', '0,2,6', '2.5']); /* between the camera and the first box */
  assert.equal(a.code, 0, a.stderr);
  const next = await drawn(page, (s) => s.last.epoch > first.last.epoch);
  assert.ok(next.last.visible > first.last.visible, `${first.last.visible} -> ${next.last.visible} drawn`);
  const c = await compare(page, await reference(page));
  assert.ok(c.mae < 4, `after the edit: mean absolute error ${c.mae.toFixed(2)}`);
  assert.equal((await cli(d, ['remove', '9'])).code, 0);
  await page.close();
});

test('a click selects the entity under it, and shows its fields', { skip }, async () => {
  const { page } = await open('format=jpeg');
  await drawn(page);
  /* where the page's camera puts box 1's centre (0, 2, 0): the same
     projection the daemon drew with */
  const at = await page.evaluate(() => {
    const r = document.getElementById('stream').getBoundingClientRect();
    return { x: r.left + r.width / 2, y: r.top + r.height / 2 };
  });
  await page.mouse.click(at.x, at.y);
  await page.waitForFunction(() => window.vantage.selected !== null, { timeout: 5000 });
  assert.equal(await page.evaluate(() => window.vantage.selected), '1');
  const text = await page.$eval('#entity', (e) => e.textContent);
  assert.match(text, /box min/);
  /* the next frames outline it: a frame drawn after the selection */
  await page.close();
});

test('touch: one finger orbits, two fingers spread zoom in', { skip }, async () => {
  const { page } = await open('format=jpeg');
  await drawn(page);
  const r = await page.$eval('#stream', (e) => { const b = e.getBoundingClientRect(); return [b.left + b.width / 2, b.top + b.height / 2]; });
  const cam0 = await page.evaluate(() => ({ ...window.vantage.camera }));
  /* one finger, 60 px to the left: the orbit turns */
  const f = await page.touchscreen.touchStart(r[0], r[1]);
  for (let i = 1; i <= 6; i++) await f.move(r[0] - 10 * i, r[1]);
  await f.end();
  const cam1 = await page.evaluate(() => ({ ...window.vantage.camera }));
  assert.ok(Math.abs(cam1.yaw - cam0.yaw) > 0.1, `yaw ${cam0.yaw} -> ${cam1.yaw}`);
  assert.equal(cam1.dist, cam0.dist);
  /* two fingers spread from 40 to 200 px apart: closer */
  const a = await page.touchscreen.touchStart(r[0] - 20, r[1]);
  const b = await page.touchscreen.touchStart(r[0] + 20, r[1]);
  for (let i = 1; i <= 8; i++) {
    await a.move(r[0] - 20 - 10 * i, r[1]);
    await b.move(r[0] + 20 + 10 * i, r[1]);
  }
  await a.end();
  await b.end();
  const cam2 = await page.evaluate(() => ({ ...window.vantage.camera }));
  assert.ok(cam2.dist < cam1.dist * 0.5, `a spread of 5x zooms in: dist ${cam1.dist} -> ${cam2.dist}`);
  await page.close();
});

test('without WebCodecs the page falls back to JPEG frames by itself', { skip }, async () => {
  const { page, errors } = await open('', { before: () => { delete window.VideoDecoder; } });
  const s = await drawn(page);
  assert.equal(s.format, 'jpeg');
  assert.deepEqual(errors, []);
  await page.close();
});

test('over TLS (--web-cert): the page over https and the protocol over wss, H.264 decoded', { skip }, async (t) => {
  /* the certificate docs/WEB.md says to make, for 127.0.0.1 */
  const key = path.join(tmp, 'key.pem'), cert = path.join(tmp, 'cert.pem');
  execFileSync('openssl', ['req', '-x509', '-newkey', 'ec', '-pkeyopt', 'ec_paramgen_curve:prime256v1', '-nodes', '-days', '1',
    '-subj', '/CN=vantage', '-addext', 'subjectAltName=IP:127.0.0.1', '-keyout', key, '-out', cert], { stdio: 'ignore' });
  const td = await startDaemon({ web: true, extra: ['--web-cert', cert, '--web-key', key] });
  /* a browser that was told to accept the self-signed certificate, as a
     user does once */
  const b = await launch({ acceptInsecureCerts: true });
  try {
    const page = await b.newPage();
    await page.goto(`https://127.0.0.1:${td.webPort}/?size=${W}x${H}#token=${TOKENS.viewer}`);
    assert.equal(await page.evaluate(() => window.isSecureContext), true);
    const s = await drawn(page);
    assert.equal(s.format, 'h264', 'WebCodecs over https');
    assert.equal(s.last.width, W);
    t.diagnostic(`over TLS: the first H.264 frame drawn, ${s.frames} decoded`);
  } finally {
    await b.close();
    await td.stop();
  }
});

test('a bad token is refused: the login field asks, a good one connects', { skip }, async () => {
  const { page } = await open('format=jpeg', { token: 'not-a-token' });
  await page.waitForSelector('#login:not([hidden])', { timeout: 5000 });
  assert.match(await page.$eval('#login-why', (e) => e.textContent), /token/);
  assert.equal(await page.evaluate(() => window.vantage.stats()), null);
  await page.type('#token', TOKENS.viewer);
  await page.click('#login button');
  const s = await drawn(page);
  assert.equal(s.last.width, W);
  await page.close();
});
