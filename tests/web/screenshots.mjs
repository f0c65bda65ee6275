/*
 * screenshots.mjs — docs/web_viewer.png and docs/web_commander.png (make
 * docs-web-shots): the demo city's daemon with --web, each page in headless
 * Chromium (Debian's) at 1600x900, an entity selected in the viewer and a
 * ping and a selection made in the commander before the shot; and
 * docs/web_viewer_moving.png, the viewer taken in the middle of a drag (a
 * frame drawn smaller and scaled up: dynamic resolution).
 *
 *   node tests/web/screenshots.mjs [OUT_DIR]   (default docs/)
 */
import { spawn } from 'node:child_process';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { launch } from './chromium.mjs';
import { freePort, BIN_DIR } from './harness.mjs';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
const out = path.resolve(process.argv[2] ?? path.join(ROOT, 'docs'));
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

const port = await freePort(), webPort = await freePort();
const d = spawn(path.join(BIN_DIR, 'vantaged'), ['--scene', 'demo', '--port', String(port), '--unix', '', '--web',
  String(webPort), '--log-level', 'warn'], { stdio: 'inherit' });
await sleep(1500);
const browser = await launch();
try {
  const page = await browser.newPage();
  await page.setViewport({ width: 1600, height: 900 });
  await page.goto(`http://127.0.0.1:${webPort}/?eye=-120,70,160&at=0,10,0`);
  await page.waitForFunction(() => window.vantage?.stats()?.last, { timeout: 30000 });
  const box = await page.$eval('#stream', (e) => { const r = e.getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; });
  await page.mouse.click(box[0] + box[2] * 0.52, box[1] + box[3] * 0.45); /* a tower near the middle */
  await page.waitForFunction(() => window.vantage.selected !== null, { timeout: 10000 }).catch(() => {});
  await sleep(2500); /* the outlined frame, the overlay's numbers */
  await page.screenshot({ path: path.join(out, 'web_viewer.png') });
  console.log(`web_viewer.png: ${JSON.stringify(await page.evaluate(() => window.vantage.selected))} selected`);
  /* the same view's neighbourhood mid-drag: the frames shown are drawn smaller */
  const cx = box[0] + box[2] * 0.3, cy = box[1] + box[3] * 0.7;
  await page.mouse.move(cx, cy);
  await page.mouse.down({ button: 'right' }); /* a pan: the city slides under the cursor */
  for (let k = 1; k <= 40; k++) {
    await page.mouse.move(cx + 3 * k, cy, { steps: 1 });
    await sleep(33);
  }
  await page.screenshot({ path: path.join(out, 'web_viewer_moving.png') });
  await page.mouse.up({ button: 'right' });
  console.log('web_viewer_moving.png: taken mid-drag');

  const c = await browser.newPage();
  await c.setViewport({ width: 1600, height: 900 });
  await c.goto(`http://127.0.0.1:${webPort}/commander.html`);
  await c.waitForFunction(() => window.vantage?.stats()?.last, { timeout: 30000 });
  /* keys held over a few of the commander's fixed ticks (a press shorter
     than a tick may fall between two) */
  const hold = async (key, ms) => { await c.keyboard.down(key); await sleep(ms); await c.keyboard.up(key); await sleep(200); };
  await hold('Tab', 150);  /* the tilted view */
  await hold('KeyD', 260); /* the reticle off the crossroads, onto a block */
  await hold('KeyW', 200);
  await c.evaluate(() => window.vantage.order('select'));
  await c.evaluate(() => window.vantage.order('ping'));
  await sleep(2500);
  await c.screenshot({ path: path.join(out, 'web_commander.png') });
  console.log(`web_commander.png: ${JSON.stringify(await c.evaluate(() => window.vantage.selected))} selected`);
} finally {
  await browser.close();
  d.kill('SIGTERM');
}
