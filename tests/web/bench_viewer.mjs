/*
 * bench_viewer.mjs — the browser viewer's numbers for BENCHMARKS.md (make
 * bench-web; not part of make test): vantaged with the demo city and --web,
 * N viewer pages in headless Chromium (Debian's), one dragging its camera
 * with real mouse events (CDP input: the page's event times), several each
 * turning its camera from a timer in the page, for S seconds; per page: frames drawn a second, and input-to-photon p50/p95
 * with its parts (the page's own measure: stream.js).
 *
 *   node tests/web/bench_viewer.mjs [--viewers N] [--seconds S] [--size WxH] [--format h264|jpeg]
 *                                   [--scene demo|empty] [--fps N] [--motion 0|1] [--motion-ms MS]
 *                                   [--daemon PATH] [--pause MS] [--json FILE]
 *
 * --motion 0: the pages ask for every frame full size (?motion=0; default
 * 1: dynamic resolution while the camera moves, vantaged --motion-ms MS).
 * --daemon: another vantaged binary (an older build, to compare in one run).
 * --pause MS: one viewer's drag rests MS ms after every 20 moves (a hand
 * that stops and starts: the full-size frame drawn at each rest is then in
 * flight when the drag goes on).
 * The daemon's metrics give how many frames were drawn smaller.
 */
import { spawn } from 'node:child_process';
import { writeFileSync } from 'node:fs';
import path from 'node:path';
import { launch } from './chromium.mjs';
import { freePort, BIN_DIR } from './harness.mjs';

const arg = (name, def) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : def;
};
const N = +arg('viewers', 1), S = +arg('seconds', 10), size = arg('size', '1280x720'), format = arg('format', 'h264');
const scene = arg('scene', 'demo'), fps = +arg('fps', 30), jsonOut = arg('json', '');
const pause = +arg('pause', 0), motion = arg('motion', '1') !== '0', motionMs = arg('motion-ms', ''), daemon = arg('daemon', path.join(BIN_DIR, 'vantaged'));

const port = await freePort(), webPort = await freePort(), metricsPort = await freePort();
const d = spawn(daemon, ['--scene', scene, '--port', String(port), '--unix', '', '--web',
  String(webPort), '--log-level', 'warn', '--max-video', String(Math.max(16, N)), '--metrics', String(metricsPort),
  ...(motionMs ? ['--motion-ms', motionMs] : [])], { stdio: 'inherit' });
/* a counter of the daemon's metrics (0 where it has none: an older build) */
const metric = async (name) => {
  const t = await (await fetch(`http://127.0.0.1:${metricsPort}/metrics`)).text();
  const m = new RegExp(`^${name} ([0-9.eE+-]+)`, 'm').exec(t);
  return m ? +m[1] : 0;
};
await new Promise((r) => setTimeout(r, 1500));
const browser = await launch();
try {
  const pages = [];
  for (let i = 0; i < N; i++) {
    const p = await browser.newPage();
    await p.setViewport({ width: 1400, height: 860 });
    await p.goto(`http://127.0.0.1:${webPort}/?size=${size}&fps=${fps}${format === 'jpeg' ? '&format=jpeg' : ''}` +
      (motion ? '' : '&motion=0'));
    pages.push(p);
  }
  for (const p of pages) {
    await p.waitForFunction(() => window.vantage?.stats()?.last, { timeout: 30000, polling: 100 /* rAF does not run in a tab behind */ }).catch(async (e) => {
      throw new Error(`${e.message}: the page says "${await p.$eval("#status", (s) => s.textContent)}", ${JSON.stringify(await p.evaluate(() => window.vantage.stats()))}`);
    });
  }
  /* the first frames (the IBL tables, cold caches) out of the way */
  await new Promise((r) => setTimeout(r, 1000));
  const start = await Promise.all(pages.map((p) => p.evaluate(() => window.vantage.stats().drawn_total)));
  const sent0 = await metric('vantage_frames_sent_total'), scaled0 = await metric('vantage_frames_scaled_total');
  const msum0 = await metric('vantage_frame_motion_scale_sum'), mcount0 = await metric('vantage_frame_motion_scale_count');
  const t0 = Date.now();
  /* one page drags with real mouse events (CDP input: the page's event
     times), 8 px every 33 ms, back and forth. Chromium delivers input to
     the tab in front only, so with several pages each turns its own
     camera from a 33 ms timer inside the page instead (the input time is
     the timer's) */
  if (N === 1) {
    const p = pages[0];
    const box = await p.$eval('#stream', (e) => { const r = e.getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; });
    let x = box[0] + box[2] / 2, dir = 1;
    const y = box[1] + box[3] / 2;
    await p.mouse.move(x, y);
    await p.mouse.down();
    for (let k = 0; Date.now() - t0 < S * 1000; k++) {
      if (k % 60 === 59) dir = -dir;
      x += 8 * dir;
      await p.mouse.move(x, y);
      await new Promise((r) => setTimeout(r, 33));
      if (pause && k % 20 === 19) await new Promise((r) => setTimeout(r, pause));
    }
    await p.mouse.up();
  } else {
    await Promise.all(pages.map((p, i) => p.evaluate((ms, sign) => new Promise((done) => {
      let k = 0;
      const id = setInterval(() => {
        window.vantage.camera.yaw += (Math.floor(k++ / 60) % 2 ? -0.01 : 0.01) * sign;
        window.vantage.aim(performance.now());
      }, 33);
      setTimeout(() => { clearInterval(id); done(); }, ms);
    }), S * 1000, i % 2 ? -1 : 1)));
  }
  const secs = (Date.now() - t0) / 1000;
  const sent = (await metric('vantage_frames_sent_total')) - sent0, scaled = (await metric('vantage_frames_scaled_total')) - scaled0;
  const mcount = (await metric('vantage_frame_motion_scale_count')) - mcount0;
  const mscale = mcount ? ((await metric('vantage_frame_motion_scale_sum')) - msum0) / mcount : NaN;
  const res = await Promise.all(pages.map((p) => p.evaluate(() => window.vantage.stats())));
  const rows = res.map((s, i) => ({ viewer: i, fps: (s.drawn_total - start[i]) / secs, p50: s.p50, p95: s.p95,
    parts_p50: s.parts_p50, kbps: s.kbps, decode_ms: s.decode_ms, samples: s.samples, format: s.format }));
  const f = (v) => (Number.isFinite(v) ? v.toFixed(1) : '-');
  console.log(`${N} viewer(s), ${size} ${format}, demo city, ${secs.toFixed(1)} s of dragging; ` +
    `${scaled} of ${sent} frames drawn smaller (dynamic resolution ${motion ? 'asked' : 'off'}` +
    `${mcount ? `; moving frames' mean scale ${mscale.toFixed(3)} of each side` : ''})`);
  for (const r of rows) {
    const p = r.parts_p50;
    console.log(`  viewer ${r.viewer}: ${f(r.fps)} fps, input->photon p50 ${f(r.p50)} p95 ${f(r.p95)} ms (${r.samples}); ` +
      `parts p50: wait ${f(p.wait)} net ${f(p.net)} render ${f(p.render)} encode ${f(p.encode)} decode ${f(p.decode)} present ${f(p.present)}; ` +
      `${f(r.kbps / 1000)} Mbit/s`);
  }
  if (jsonOut) writeFileSync(jsonOut, JSON.stringify({ viewers: N, size, format, motion, seconds: secs, sent, scaled, motion_scale: mscale, rows }, null, 1));
} finally {
  await browser.close();
  d.kill('SIGTERM');
}
