/*
 * harness.mjs — what the web client's tests share: the real vantaged of
 * this build (VANTAGE_BIN_DIR, default build/release) on a free port with a
 * temporary data directory and a token file, the C CLI `vantage` against
 * it (the independent model the tests hold web/js/vproto.js to), a Node
 * net.Socket as a vproto Client transport, and a recording TCP proxy that
 * keeps the bytes both ways (the CLI's requests, the daemon's replies).
 * Each test file starts its own daemon (about 30 ms) and stops it, checking
 * the clean exit, so files share no scene and may run in any order.
 */
import { spawn, execFile } from 'node:child_process';
import { mkdtempSync, writeFileSync, rmSync, existsSync } from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { Client, ROLE } from '../../web/js/vproto.js';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
export const BIN_DIR = path.resolve(ROOT, process.env.VANTAGE_BIN_DIR ?? 'build/release');

export const TOKENS = Object.freeze({
  viewer: 'web-viewer-token-0123456789abcdef',
  commander: 'web-commander-token-0123456789ab',
  editor: 'web-editor-token-0123456789abcdef',
});

/* A TCP port nothing listens on now (the kernel's pick). */
export function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.once('error', reject);
    s.listen(0, '127.0.0.1', () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
  });
}

/* A connected net.Socket as a vproto transport. */
export function tcpTransport(port, host = '127.0.0.1') {
  return new Promise((resolve, reject) => {
    const sock = net.connect({ port, host });
    sock.setNoDelay(true);
    const t = {
      sock,
      onbytes: null,
      onclose: null,
      send(b) { sock.write(b); },
      close() { sock.destroy(); },
    };
    sock.once('error', reject);
    sock.on('connect', () => {
      sock.off('error', reject);
      sock.on('error', () => {}); // 'close' follows
      resolve(t);
    });
    sock.on('data', (chunk) => t.onbytes && t.onbytes(chunk));
    sock.on('close', () => t.onclose && t.onclose({ reason: 'socket closed' }));
  });
}

/* A Client over TCP after HELLO with role and token (default: that role's
 * token). Rejects with the HELLO's VpError. */
export async function connect(d, role = ROLE.VIEWER, token, opts = {}) {
  const c = new Client(await tcpTransport(d.port), { timeoutMs: 5000, ...opts });
  const tok = token ?? TOKENS[['viewer', 'commander', 'editor'][role]];
  try {
    await c.hello({ role, token: tok, name: 'tests/web' });
  } catch (e) {
    c.close();
    throw e;
  }
  return c;
}

/* vantage -p PORT args..., with VANTAGE_TOKEN (default the editor's) and
 * input on its stdin (closed at once without): { code, stdout, stderr }. */
export function cli(d, args, { token = TOKENS.editor, input = '' } = {}) {
  return new Promise((resolve) => {
    const child = execFile(path.join(BIN_DIR, 'vantage'), ['-p', String(d.port), ...args],
      { env: { ...process.env, VANTAGE_TOKEN: token }, timeout: 10000, encoding: 'buffer' },
      (err, stdout, stderr) => resolve({ code: err ? (err.code ?? -1) : 0, stdout: stdout.toString(), stderr: stderr.toString(), out: stdout }));
    child.stdin.end(input);
  });
}

/* The JSON lines the CLI printed, parsed. Ids above 2^53 would lose bits
 * in JSON.parse, so "id" values are read as BigInt from the text. */
export function jsonLines(text) {
  return text.split('\n').filter((l) => l.startsWith('{')).map((l) =>
    JSON.parse(l.replace(/"id": (\d+)/g, '"id": "$1"'), (k, v) => (k === 'id' ? BigInt(v) : v)));
}

/*
 * Starts vantaged: the empty scene, TCP on a free loopback port, no Unix
 * socket, a temporary --data-dir and a --tokens file (viewer, commander,
 * editor: TOKENS) unless tokens is false; with web, --web on another free
 * port (webPort). Waits until a HELLO is answered.
 * Returns { port, webPort, dataDir, stop() }; stop() sends SIGTERM and rejects
 * unless the daemon exits with status 0.
 */
export async function startDaemon({ tokens = true, web = false, extra = [] } = {}) {
  const bin = path.join(BIN_DIR, 'vantaged');
  if (!existsSync(bin)) throw new Error(`${bin} is missing: build it (make CONFIG=release all) or set VANTAGE_BIN_DIR`);
  const dataDir = mkdtempSync(path.join(os.tmpdir(), 'vantage-web-'));
  const port = await freePort();
  const webPort = web ? await freePort() : 0;
  const args = ['--scene', 'empty', '--port', String(port), '--unix', '', '--data-dir', path.join(dataDir, 'data'),
    '--log-level', 'warn', '--threads', '1', ...(web ? ['--web', `127.0.0.1:${webPort}`] : []), ...extra];
  if (tokens) {
    const f = path.join(dataDir, 'tokens');
    writeFileSync(f, `viewer ${TOKENS.viewer}\ncommander ${TOKENS.commander}\neditor ${TOKENS.editor}\n`, { mode: 0o600 });
    args.push('--tokens', f);
  }
  const proc = spawn(bin, args, { stdio: ['ignore', 'ignore', 'pipe'] });
  // a test file that dies without its after hook takes its daemon along
  const reap = () => proc.kill('SIGKILL');
  process.once('exit', reap);
  proc.once('exit', () => process.off('exit', reap));
  let stderr = '';
  proc.stderr.on('data', (b) => { stderr += b; });
  const exited = new Promise((resolve) => proc.on('exit', (code, signal) => resolve({ code, signal })));
  const d = { port, webPort, dataDir, proc, get stderr() { return stderr; } };
  d.stop = async () => {
    if (proc.exitCode === null && proc.signalCode === null) proc.kill('SIGTERM');
    const { code, signal } = await exited;
    rmSync(dataDir, { recursive: true, force: true });
    if (code !== 0) throw new Error(`vantaged exited with ${signal ?? `status ${code}`}: ${stderr}`);
  };
  for (let i = 0; ; i++) { // until it answers (about 20 ms on an idle machine)
    try {
      (await connect(d, ROLE.VIEWER, tokens ? TOKENS.viewer : '')).close();
      return d;
    } catch (e) {
      if (proc.exitCode !== null || i >= 500) {
        await d.stop().catch(() => {});
        throw new Error(`vantaged did not start: ${e.message}; ${stderr}`);
      }
      await new Promise((r) => setTimeout(r, 10));
    }
  }
}

/*
 * A TCP proxy to the daemon that records what passes: each accepted
 * connection adds { up: [chunks client -> daemon], down: [chunks daemon ->
 * client] } to conns. Returns { port, conns, close() }.
 */
export async function recordingProxy(d) {
  const conns = [];
  const server = net.createServer((c) => {
    const rec = { up: [], down: [] };
    conns.push(rec);
    const s = net.connect({ port: d.port, host: '127.0.0.1' });
    c.on('data', (b) => { rec.up.push(Buffer.from(b)); s.write(b); });
    s.on('data', (b) => { rec.down.push(Buffer.from(b)); c.write(b); });
    c.on('close', () => s.destroy());
    s.on('close', () => c.destroy());
    c.on('error', () => {});
    s.on('error', () => {});
  });
  await new Promise((r) => server.listen(0, '127.0.0.1', r));
  return { port: server.address().port, conns, close: () => new Promise((r) => server.close(r)) };
}

/* Resolves with the first value pred(...) accepts among calls of the
 * callback it installs as obj[name]; rejects after ms. */
export function waitFor(obj, name, pred = () => true, ms = 5000) {
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => { obj[name] = null; reject(new Error(`no ${name} in ${ms} ms`)); }, ms);
    obj[name] = (...a) => {
      if (!pred(...a)) return;
      clearTimeout(timer);
      obj[name] = null;
      resolve(a.length > 1 ? a : a[0]);
    };
  });
}
