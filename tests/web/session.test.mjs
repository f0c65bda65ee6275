/*
 * session.test.mjs — vproto.js against the real vantaged (with --tokens):
 * HELLO with each role's token and refusals with the daemon's own ERROR
 * (the C CLI given the same bad token prints the same message), PING,
 * the stream parser on a recorded reply stream in 1-byte chunks and in one
 * chunk, bad frames from the JS side answered with the daemon's ERROR (the
 * promise rejects with its code name, the connection goes on), and
 * wsTransport over a WebSocket stand-in that carries the same stream.
 */
import test from 'node:test';
import assert from 'node:assert/strict';
import net from 'node:net';
import { startDaemon, connect, cli, TOKENS, tcpTransport } from './harness.mjs';
import {
  Client, ROLE, T, enc, FrameParser, VpError, wsTransport, viewPerspective, VP_HEADER_SIZE,
} from '../../web/js/vproto.js';

let d;
test.before(async () => { d = await startDaemon(); });
test.after(async () => { await d.stop(); });

test('HELLO with each role\'s token is granted that role', async () => {
  for (const role of [ROLE.VIEWER, ROLE.COMMANDER, ROLE.EDITOR]) {
    const c = await connect(d, role);
    const ok = c.helloOk;
    assert.equal(ok.version, 2);
    assert.equal(ok.role, role);
    assert.equal(ok.max_payload, 16777216, 'vantaged --help: --max-payload default');
    assert.equal(ok.max_views, 32);
    assert.equal(typeof ok.epoch, 'bigint');
    assert.ok(ok.client_id > 0);
    c.close();
  }
  // a higher role's token serves a lower role (PROTOCOL.md: editor > commander > viewer)
  const c = await connect(d, ROLE.VIEWER, TOKENS.editor);
  assert.equal(c.helloOk.role, ROLE.VIEWER);
  c.close();
});

test('bad tokens are refused with the daemon\'s AUTH, as the CLI is', async () => {
  const cases = [
    [ROLE.VIEWER, 'not-the-viewer-token-at-all'],
    [ROLE.VIEWER, ''],
    [ROLE.EDITOR, TOKENS.viewer],
    [ROLE.COMMANDER, TOKENS.viewer],
  ];
  for (const [role, token] of cases) {
    const c = new Client(await tcpTransport(d.port), { timeoutMs: 5000 });
    const closed = new Promise((resolve) => { c.onclose = resolve; });
    const err = await c.hello({ role, token }).then(() => null, (e) => e);
    assert.ok(err instanceof VpError, `role ${role} token "${token}" was granted`);
    assert.equal(err.codeName, 'AUTH');
    assert.equal(err.code, -11);
    assert.equal(err.local, false);
    await closed; // the daemon closes the connection after a refused HELLO
    await assert.rejects(c.ping(), (e) => e.codeName === 'CLOSED');
  }
  // the CLI with the viewer's wrong token: refused, and the daemon's message is the one JS got
  const c = new Client(await tcpTransport(d.port));
  const err = await c.hello({ role: ROLE.VIEWER, token: 'not-the-viewer-token-at-all' }).catch((e) => e);
  const r = await cli(d, ['ping'], { token: 'not-the-viewer-token-at-all' });
  assert.equal(r.code, 3, 'vantage counts a refused HELLO as "cannot connect" (exit 3)');
  const msg = err.message.replace(/^AUTH: /, '');
  assert.ok(msg.length > 0);
  assert.ok(r.stderr.includes(msg), `CLI: ${r.stderr} / JS: ${msg}`);
});

test('PING echoes its bytes; requests pipeline and resolve by req', async () => {
  const c = await connect(d, ROLE.VIEWER);
  const data = [new Uint8Array([]), new Uint8Array([0, 255, 7]), new Uint8Array(1024).map((_, i) => i * 7)];
  const pongs = await Promise.all(data.map((b) => c.ping(b)));
  pongs.forEach((p, i) => assert.deepEqual([...p], [...data[i]]));
  const st = await c.stats();
  assert.equal(st.entities, 0);
  c.close();
});

/* HELLO and a pipeline of requests written at once on a raw socket: the
 * daemon's reply bytes, as they arrived, until `n` frames are complete
 * by the headers' lengths. */
async function recordReplies(requests, n) {
  const sock = net.connect({ port: d.port, host: '127.0.0.1' });
  await new Promise((r) => sock.once('connect', r));
  const chunks = [];
  const done = new Promise((resolve) => {
    sock.on('data', (b) => {
      chunks.push(b);
      const all = Buffer.concat(chunks);
      let at = 0, k = 0;
      while (at + VP_HEADER_SIZE <= all.length && at + VP_HEADER_SIZE + all.readUInt32LE(at) <= all.length) {
        at += VP_HEADER_SIZE + all.readUInt32LE(at);
        k++;
      }
      if (k >= n) resolve(all);
    });
  });
  sock.write(Buffer.concat(requests.map((b) => Buffer.from(b))));
  const all = await done;
  sock.destroy();
  return { all, chunks };
}

test('the stream parser: a recorded reply stream in 1-byte chunks and in one chunk gives the same frames', async () => {
  const view = viewPerspective({ eye: [0, 2, 10], target: [0, 2, 0], width: 32, height: 24 });
  const reqs = [
    enc.hello(1, { role: ROLE.VIEWER, token: TOKENS.viewer }),
    enc.ping(2, new Uint8Array([1, 2, 3])),
    enc.empty(T.STATS, 3),
    enc.entityGet(4, [12345n]), // unknown: ERROR
    enc.raw(0x0777, 5), // unknown type: ERROR
    enc.visQuery(6, [view]),
    enc.render(7, { view, quality: 50 }),
    enc.empty(T.SUBLEVEL_LIST, 8),
    enc.ping(9, new Uint8Array(1000).fill(9)),
  ];
  const { all } = await recordReplies(reqs, reqs.length);
  const strip = (fs) => fs.map((f) => ({ type: f.type, req: f.req, payload: Buffer.from(f.payload).toString('hex') }));
  const one = strip(new FrameParser().push(all));
  const bytewise = [];
  const p = new FrameParser();
  for (let i = 0; i < all.length; i++) bytewise.push(...p.push(all.subarray(i, i + 1)));
  assert.deepEqual(strip(bytewise), one);
  assert.equal(p.buffered, 0);
  // and the frames are the replies asked for, in order
  assert.deepEqual(one.map((f) => f.req), [1, 2, 3, 4, 5, 6, 7, 8, 9]);
  assert.deepEqual(one.map((f) => f.type),
    [T.HELLO_OK, T.PONG, T.STATS_REPLY, T.ERROR, T.ERROR, T.VIS_RESULT, T.FRAME, T.SUBLEVEL_LIST_REPLY, T.PONG]);
  assert.ok(all.length > 1000, 'the FRAME makes the stream long enough to span socket reads');
});

test('bad frames from the JS side get the daemon\'s ERROR; the promise rejects with its code name', async () => {
  const c = await connect(d, ROLE.VIEWER);
  const bad = async (type, payload, replyType = null) =>
    c.call(type, (req) => enc.raw(type, req, payload), replyType).then(() => null, (e) => e);
  let e = await bad(T.ENTITY_GET, new Uint8Array(2), T.ENTITY_LIST_REPLY); // count cut short
  assert.equal(e.codeName, 'TRUNCATED');
  assert.equal(e.local, false);
  e = await bad(0x0777, new Uint8Array(5)); // no such type
  assert.equal(e.codeName, 'TYPE');
  e = await bad(T.STATS, new Uint8Array(3), T.STATS_REPLY); // an empty message with bytes
  assert.equal(e.codeName, 'TRAILING');
  e = await c.entityGet([424242n]).catch((x) => x);
  assert.equal(e.codeName, 'UNKNOWN_ID');
  // a viewer may not MARK or DESTROY
  e = await c.mark({ pos: [0, 0, 0] }).catch((x) => x);
  assert.equal(e.codeName, 'AUTH');
  e = await c.destroy({ id: 1n, center: [0, 0, 0], radius: 1 }).catch((x) => x);
  assert.equal(e.codeName, 'AUTH');
  // a view that is all zeros is no camera: MATRIX, naming view 0
  e = await c.visQuery([{}]).catch((x) => x);
  assert.equal(e.codeName, 'MATRIX');
  assert.equal(e.index, 0);
  // NaN where a number must be finite
  const v = viewPerspective({ eye: [0, 0, 10], target: [0, 0, 0], width: 8, height: 8 });
  e = await c.visQuery([{ ...v, origin: [NaN, 0, 0] }]).catch((x) => x);
  assert.equal(e.codeName, 'NONFINITE');
  // the connection went on through all of it
  assert.deepEqual([...(await c.ping(new Uint8Array([42])))], [42]);
  c.close();
});

test('a request over the limit before HELLO is refused here, not sent; HELLO then works', async () => {
  const c = new Client(await tcpTransport(d.port), { timeoutMs: 5000 });
  const e = await c.call(T.PING, (req) => enc.raw(T.PING, req, new Uint8Array(4097)), T.PONG).catch((x) => x);
  assert.equal(e.codeName, 'TOO_LARGE');
  assert.equal(e.local, true);
  const ok = await c.hello({ role: ROLE.VIEWER, token: TOKENS.viewer });
  assert.equal(ok.role, ROLE.VIEWER);
  c.close();
});

/* A stand-in for the browser's WebSocket that carries the protocol stream
 * over TCP to the daemon (what daemon/web.c will carry over a real
 * WebSocket): each socket read is one binary message of an ArrayBuffer. */
class TcpWebSocket {
  constructor(url) {
    this.url = url;
    this.binaryType = 'blob';
    const port = Number(new URL(url).port);
    this.sock = net.connect({ port, host: '127.0.0.1' });
    this.sock.on('connect', () => this.onopen && this.onopen({}));
    this.sock.on('data', (b) => {
      assert.equal(this.binaryType, 'arraybuffer', 'wsTransport asks for ArrayBuffers');
      const ab = b.buffer.slice(b.byteOffset, b.byteOffset + b.length);
      this.onmessage && this.onmessage({ data: ab });
    });
    this.sock.on('error', () => {});
    this.sock.on('close', () => this.onclose && this.onclose({ code: this.code ?? 1006, reason: '' }));
  }
  send(b) { this.sock.write(b); }
  close(code = 1000) { this.code = code; this.sock.destroy(); }
}

test('wsTransport: a Client over a WebSocket speaks the same stream', async () => {
  const t = await wsTransport(`ws://127.0.0.1:${d.port}/ws`, { WebSocketImpl: TcpWebSocket });
  const c = new Client(t, { timeoutMs: 5000 });
  const ok = await c.hello({ role: ROLE.COMMANDER, token: TOKENS.commander });
  assert.equal(ok.role, ROLE.COMMANDER);
  assert.deepEqual([...(await c.ping(new Uint8Array([5, 6])))], [5, 6]);
  const closed = new Promise((resolve) => { c.onclose = resolve; });
  c.close();
  assert.equal((await closed).code, 1000);
  // a text message is no part of the protocol: the transport closes (1003)
  const t2 = await wsTransport(`ws://127.0.0.1:${d.port}/ws`, { WebSocketImpl: TcpWebSocket });
  const c2 = new Client(t2);
  const closed2 = new Promise((resolve) => { c2.onclose = resolve; });
  t2.ws.onmessage({ data: 'hello' });
  assert.equal((await closed2).code, 1003);
  // no WebSocket at all: a clear refusal
  await assert.rejects(wsTransport('ws://x/ws', { WebSocketImpl: null }), (e) => e.codeName === 'UNSUPPORTED');
});
