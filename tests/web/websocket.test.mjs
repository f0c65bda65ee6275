/*
 * websocket.test.mjs — vproto.js over the daemon's real WebSocket
 * (vantaged --web, daemon/web.c) with the WebSocket client Node 20 has
 * behind --experimental-websocket (run.sh passes it; Node 22 has it
 * always): the page's module is served as JavaScript byte for byte, HELLO
 * and refusals, a JPEG stream whose frames are the TCP RENDER's JPEG of the
 * same view, an edit's frame, a request cut into 1-byte messages, and a bad
 * frame's ERROR with the socket going on.
 */
import test from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { startDaemon, connect, cli, TOKENS, waitFor } from './harness.mjs';
import { Client, ROLE, T, enc, wsTransport, viewPerspective, VP_FRAME_JPEG } from '../../web/js/vproto.js';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
const hasWs = typeof globalThis.WebSocket === 'function';
const opts = { skip: hasWs ? false : 'no WebSocket in this Node (run.sh passes --experimental-websocket on Node 20)' };

let d;
test.before(async () => {
  d = await startDaemon({ web: true });
  for (const [id, pos, r] of [[1, '0,1,-10', 2], [2, '5,1,-20', 3]]) assert.equal((await cli(d, ['add', String(id), pos, String(r)])).code, 0);
});
test.after(async () => { if (d) await d.stop(); });

const url = () => `ws://127.0.0.1:${d.webPort}/ws`;
async function wsClient(role, token) {
  const c = new Client(await wsTransport(url()), { timeoutMs: 5000 });
  await c.hello({ role, token, name: 'tests/web websocket' });
  return c;
}

test('the page gets web/js/vproto.js as JavaScript, byte for byte', async () => {
  const r = await fetch(`http://127.0.0.1:${d.webPort}/js/vproto.js`);
  assert.equal(r.status, 200);
  assert.match(r.headers.get('content-type'), /^text\/javascript/, 'a module script needs a JavaScript MIME type');
  assert.ok(Buffer.from(await r.arrayBuffer()).equals(readFileSync(path.join(ROOT, 'web/js/vproto.js'))));
});

test('HELLO over the WebSocket; a bad token is AUTH and the socket closes', opts, async () => {
  const c = await wsClient(ROLE.COMMANDER, TOKENS.commander);
  assert.equal(c.helloOk.role, ROLE.COMMANDER);
  assert.deepEqual([...(await c.ping(new Uint8Array([3, 1, 4])))], [3, 1, 4]);
  c.close();
  const b = new Client(await wsTransport(url()), { timeoutMs: 5000 });
  const closed = new Promise((resolve) => { b.onclose = resolve; });
  const e = await b.hello({ role: ROLE.VIEWER, token: 'wrong' }).catch((x) => x);
  assert.equal(e.codeName, 'AUTH');
  await closed;
});

test('a JPEG stream over the WebSocket: the TCP RENDER\'s picture, then an edit\'s frame', opts, async () => {
  const view = viewPerspective({ eye: [2, 6, 12], target: [0, 1, -12], width: 96, height: 64 });
  const tcp = await connect(d, ROLE.VIEWER);
  const still = await tcp.render({ view, format: VP_FRAME_JPEG, quality: 70 });
  const c = await wsClient(ROLE.VIEWER, TOKENS.viewer);
  const first = waitFor(c, 'onframe');
  const sub = await c.frameSubscribe({ view, format: VP_FRAME_JPEG, quality: 70, maxFps: 60, viewSeq: 3 });
  const [f1, req] = await first;
  assert.equal(req, sub.req);
  assert.equal(f1.view_seq, 3);
  assert.equal(f1.epoch, still.epoch);
  assert.ok(Buffer.from(f1.data).equals(Buffer.from(still.data)), 'the same JPEG as RENDER over TCP');
  const next = waitFor(c, 'onframe', (f) => f.epoch > f1.epoch);
  const a = await cli(d, ['add', '3', '-2,1,-8', '1']);
  assert.equal(a.code, 0, a.stderr);
  const [f2] = await next;
  assert.equal(f2.epoch, BigInt(/at epoch (\d+)/.exec(a.stdout)[1]));
  assert.equal(f2.visible, 3);
  await c.frameUnsubscribe();
  c.close();
  tcp.close();
});

test('a request cut into 1-byte messages is one request; a bad frame gets ERROR and the socket goes on', opts, async () => {
  const c = await wsClient(ROLE.VIEWER, TOKENS.viewer);
  const send = c.t.send;
  c.t.send = (b) => { for (let i = 0; i < b.length; i++) send(b.subarray(i, i + 1)); };
  const got = await c.entityGet([1n, 2n]);
  assert.deepEqual(got.entities.map((e) => e.id), [1n, 2n]);
  c.t.send = send;
  const e = await c.call(0x0777, (req) => enc.raw(0x0777, req, new Uint8Array(3)), null).catch((x) => x);
  assert.equal(e.codeName, 'TYPE');
  assert.equal(e.local, false);
  const t = await c.call(T.ENTITY_GET, (req) => enc.raw(T.ENTITY_GET, req, new Uint8Array(2)), T.ENTITY_LIST_REPLY).catch((x) => x);
  assert.equal(t.codeName, 'TRUNCATED');
  assert.deepEqual([...(await c.ping(new Uint8Array([9])))], [9]);
  c.close();
});
