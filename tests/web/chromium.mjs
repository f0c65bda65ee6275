/*
 * chromium.mjs — headless Chromium for the browser tests, the bench and
 * the screenshots: Debian's /usr/bin/chromium (VANTAGE_CHROMIUM to name
 * another) driven by puppeteer-core, pinned in package.json (npm ci in
 * make deps; it downloads no browser).
 */
import { existsSync } from 'node:fs';

export const CHROMIUM = process.env.VANTAGE_CHROMIUM ?? '/usr/bin/chromium';
let puppeteer = null;
try {
  puppeteer = (await import('puppeteer-core')).default;
} catch {
  /* make deps runs npm ci in tests/web */
}

/* Why a browser test cannot run here (node:test's skip), or false. */
export const skipReason = !puppeteer ? 'puppeteer-core is not installed (make deps: npm ci in tests/web)'
  : !existsSync(CHROMIUM) ? `no ${CHROMIUM} (make deps installs Debian's chromium)` : false;

/* The browser: headless, no sandbox (tests run as root), software
 * rendering, and no throttling of the tabs behind the front one (each page
 * is a tab; a bench runs several at once). */
export function launch(more = {}) {
  return puppeteer.launch({ ...more, executablePath: CHROMIUM, headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage', '--disable-background-timer-throttling',
      '--disable-backgrounding-occluded-windows', '--disable-renderer-backgrounding'] });
}

/* A --web daemon (two workers) holding bounds entities [id, 'x,y,z', r]
 * added by the CLI, and a browser: { d, browser, stop() }. */
export async function webDaemonAndBrowser(boxes) {
  const { startDaemon, cli } = await import('./harness.mjs');
  const d = await startDaemon({ web: true, extra: ['--threads', '2'] });
  for (const [id, pos, r] of boxes) {
    const a = await cli(d, ['add', String(id), pos, String(r)]);
    if (a.code !== 0) throw new Error(`vantage add ${id}: ${a.stderr}`);
  }
  const browser = await launch();
  return { d, browser, async stop() { await browser.close(); await d.stop(); } };
}
