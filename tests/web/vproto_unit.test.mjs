/*
 * vproto_unit.test.mjs — web/js/vproto.js without a daemon: its layouts
 * against PROTOCOL.md's layout tables (the spec, read independently), the
 * stream parser against a slow reference walker over every chunking, the
 * parser's refusals, the writer's refusals of values it cannot encode, the
 * decoders' refusals, and the Client's request bookkeeping over an
 * in-memory transport (timeouts, close, pushes, throwing callbacks).
 */
import test from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import {
  LAYOUTS, FrameParser, Writer, Reader, VpError, enc, dec, decode, T, Client, VP_HEADER_SIZE,
  VP_FRAME_H264, VP_FRAME_JPEG, putLayout, encodeFrame, viewPerspective, viewOrtho, errName, typeName, ERR,
} from '../../web/js/vproto.js';

/* assert.throws that returns the VpError thrown (the node:assert one returns nothing) */
function throwsVp(f, check) {
  try {
    f();
  } catch (e) {
    assert.ok(e instanceof VpError, `not a VpError: ${e}`);
    if (typeof check === 'function' && check !== VpError) assert.ok(check(e));
    return e;
  }
  assert.fail('no error thrown');
}

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');

/* PROTOCOL.md's `<!-- layout: name [at N] -->` tables: the fixed rows
 * (numeric offset and size, a type) as { offset, size, type, name },
 * offsets relative to N. */
function docLayouts() {
  const lines = readFileSync(path.join(ROOT, 'protocol/PROTOCOL.md'), 'utf8').split('\n');
  const out = new Map();
  for (let i = 0; i < lines.length; i++) {
    const m = /^<!-- layout: (\w+)(?: at (\d+))? -->$/.exec(lines[i].trim());
    if (!m) continue;
    const at = m[2] ? +m[2] : 0;
    const rows = [];
    for (let j = i + 3; j < lines.length && lines[j].startsWith('|'); j++) {
      const c = lines[j].split('|').slice(1, -1).map((s) => s.trim());
      if (!/^\d+$/.test(c[0]) || !/^\d+$/.test(c[1])) break; // the fixed part ends
      if (+c[0] < at) continue;
      if (!c[2]) break; // a nested record (MARKED's MARK): not this layout's field
      rows.push({ offset: +c[0] - at, size: +c[1], type: c[2], name: c[3].replace(/`/g, '') });
    }
    out.set(m[1], rows);
  }
  return out;
}

test('every layout is PROTOCOL.md\'s table: offsets, sizes, types, names', () => {
  const doc = docLayouts();
  const undocumented = ['frame_sub_tail']; // FRAME_SUBSCRIBE's tail has a plain table
  for (const [name, L] of Object.entries(LAYOUTS)) {
    if (undocumented.includes(name)) continue;
    assert.ok(doc.has(name), `PROTOCOL.md has no "layout: ${name}" table`);
    const mine = L.fields.map((f) => ({ offset: f.offset, size: f.size, type: f.count ? `${f.type}[${f.count}]` : f.type, name: f.name }));
    assert.deepEqual(mine, doc.get(name), `layout ${name}`);
  }
});

test('message types and error codes are protocol.h\'s (enum vp_type, VP_ERRORS)', () => {
  const h = readFileSync(path.join(ROOT, 'protocol/protocol.h'), 'utf8');
  const types = Object.fromEntries([...h.matchAll(/^\s*VP_(\w+) = (0x[0-9a-fA-F]+),/gm)].map((m) => [m[1], Number(m[2])]));
  assert.deepEqual(T, types);
  const errs = Object.fromEntries([...h.matchAll(/X\(VP_ERR_(\w+),\s*(-\d+),/g)].map((m) => [m[1], Number(m[2])]));
  assert.deepEqual(ERR, errs);
  assert.equal(Object.keys(ERR).length, 24);
});

/* A deterministic PRNG (mulberry32): the same cases every run. */
function rng(seed) {
  return () => {
    seed = (seed + 0x6d2b79f5) | 0;
    let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/* The reference: walk the headers of a whole stream by offset. */
function walk(stream) {
  const dv = new DataView(stream.buffer, stream.byteOffset, stream.byteLength);
  const out = [];
  for (let at = 0; at < stream.length;) {
    const len = dv.getUint32(at, true);
    out.push({ type: dv.getUint16(at + 4, true), req: dv.getUint32(at + 8, true), payload: [...stream.subarray(at + 12, at + 12 + len)] });
    at += 12 + len;
  }
  return out;
}

function synthStream(n, rand) {
  const w = new Writer();
  for (let i = 0; i < n; i++) {
    const len = [0, 1, 11, 12, 13, 300, 5000][Math.floor(rand() * 7)];
    w.begin(1 + Math.floor(rand() * 0x700), Math.floor(rand() * 0xffffffff));
    const p = new Uint8Array(len).map(() => Math.floor(rand() * 256));
    w.bytes(p);
    w.end();
  }
  return w.view().slice();
}

function parseChunked(stream, sizes) {
  const p = new FrameParser();
  const out = [];
  for (let at = 0, k = 0; at < stream.length; k++) {
    const n = sizes(k);
    for (const f of p.push(stream.subarray(at, at + n))) out.push({ type: f.type, req: f.req, payload: [...f.payload] });
    at += n;
  }
  assert.equal(p.buffered, 0);
  return out;
}

test('the stream parser gives the reference\'s frames in every chunking', () => {
  const rand = rng(21);
  const stream = synthStream(60, rand);
  const want = walk(stream);
  assert.equal(want.length, 60);
  assert.deepEqual(parseChunked(stream, () => 1), want, '1-byte chunks');
  assert.deepEqual(parseChunked(stream, () => stream.length), want, 'one chunk');
  for (const s of [5, 12, 13, 4096]) assert.deepEqual(parseChunked(stream, () => s), want, `${s}-byte chunks`);
  for (let r = 0; r < 20; r++) assert.deepEqual(parseChunked(stream, () => 1 + Math.floor(rand() * 700)), want, 'random chunks');
  // a frame inside one chunk is a view of it, not a copy
  const frames = new FrameParser().push(stream);
  assert.ok(frames.every((f) => f.payload.buffer === stream.buffer));
});

test('the stream parser refuses non-zero flags and oversize lengths from the header alone', () => {
  const w = new Writer();
  w.begin(T.PONG, 7);
  w.bytes(new Uint8Array([1, 2, 3]));
  w.end();
  const good = w.view().slice();
  const badFlags = good.slice();
  badFlags[6] = 1; // flags
  const p = new FrameParser();
  let err = throwsVp(() => p.push(new Uint8Array([...good, ...badFlags])), VpError);
  assert.equal(err.codeName, 'INVALID');
  assert.match(err.message, /flags 0x1/);
  assert.equal(err.frames.length, 1, 'the good frame before it is kept');
  assert.equal(err.frames[0].req, 7);
  throwsVp(() => p.push(good), (e) => e === err, 'the parser stays failed');

  const big = new FrameParser({ maxPayload: 1000 });
  const h = new DataView(new ArrayBuffer(12));
  h.setUint32(0, 1001, true);
  h.setUint16(4, T.FRAME, true);
  err = throwsVp(() => big.push(new Uint8Array(h.buffer)), VpError); // the header alone
  assert.equal(err.codeName, 'TOO_LARGE');
  assert.match(err.message, /1001 bytes is over the limit of 1000/);
  h.setUint32(0, 1000, true);
  assert.deepEqual(new FrameParser({ maxPayload: 1000 }).push(new Uint8Array(h.buffer)), []);
});

test('the writer refuses what it cannot encode, naming the field', () => {
  const cases = [
    [() => enc.mark(1, { pos: [0, 0, 0], kind: 300 }), /mark kind 300 is not an integer in 0\.\.255/],
    [() => enc.mark(1, { pos: [0, 0] }), /mark pos has 2 elements, not 3/],
    [() => enc.mark(1, { pos: [0, 'x', 0] }), /mark pos\[1\] is not a number/],
    [() => enc.destroy(1, { id: -1n, center: [0, 0, 0], radius: 1 }), /destroy id -1 is outside 0\.\.2\^64-1/],
    [() => enc.destroy(1, { id: 2n ** 64n, center: [0, 0, 0], radius: 1 }), /outside 0\.\.2\^64-1/],
    [() => enc.entityGet(1, [2 ** 60]), /id 0 1152921504606847000 is not a BigInt or a safe integer/],
    [() => enc.hello(1, { token: 'x'.repeat(256) }), /token is 256 bytes; at most 255/],
    [() => enc.sublevelNames(1, ['ok', 'é'.repeat(128)]), /name 1 is 256 bytes/],
    [() => enc.render(1, { view: {}, highlight: new Array(9).fill(1) }), /9 highlights; at most 8/],
    [() => enc.frameSubscribe(1, { view: {}, maxFps: 70000 }), /max_fps 70000/],
    [() => viewPerspective({ eye: [0, 0, 0], target: [0, 0, -1], width: 1e6, height: 10 }), /width 1000000 is not a viewport side/],
    [() => viewPerspective({ eye: [0, 0, 0], target: [0, 0, -1], width: 8, height: 8, near: '0.5' }), /near is not a number/],
    [() => viewPerspective({ eye: [0, 0], target: [0, 0, -1], width: 8, height: 8 }), /eye is not 3 numbers/],
  ];
  for (const [f, re] of cases) {
    const e = throwsVp(f, VpError);
    assert.equal(e.codeName, e.codeName === 'COUNT' ? 'COUNT' : 'INVALID');
    assert.match(e.message, re);
  }
});

test('decoders refuse payloads that do not hold their message', () => {
  const ok = new Writer();
  putLayout(ok, LAYOUTS.hello_ok, { version: 2, max_payload: 4096, epoch: 5n, client_id: 9 });
  const p = ok.view().slice();
  assert.equal(decode(T.HELLO_OK, p).epoch, 5n);
  const codeOf = (f) => { try { f(); } catch (e) { return e.codeName; } return 'OK'; };
  assert.equal(codeOf(() => decode(T.HELLO_OK, p.subarray(0, 27))), 'TRUNCATED');
  assert.equal(codeOf(() => decode(T.HELLO_OK, new Uint8Array([...p, 0]))), 'TRAILING');
  assert.equal(codeOf(() => decode(0x0777, p)), 'TYPE');

  const vr = new Writer();
  putLayout(vr, LAYOUTS.vis_result, { count: 2 });
  vr.zeros(24); // one record of the two
  assert.equal(codeOf(() => decode(T.VIS_RESULT, vr.view())), 'COUNT');

  const frame = (m, data) => {
    const w = new Writer();
    putLayout(w, LAYOUTS.frame, { width: 4, height: 2, data_len: data.length, ...m });
    w.bytes(data);
    return w.view().slice();
  };
  const jpeg = new Uint8Array([0xff, 0xd8, 0xff, 0xd9]);
  const f = decode(T.FRAME, frame({ format: VP_FRAME_JPEG }, jpeg));
  assert.deepEqual([...f.data], [...jpeg]);
  assert.equal(decode(T.FRAME, frame({ format: VP_FRAME_H264 }, jpeg)).format, VP_FRAME_H264);
  assert.equal(codeOf(() => decode(T.FRAME, frame({ format: 3 }, jpeg))), 'INVALID');
  assert.equal(codeOf(() => decode(T.FRAME, frame({ width: 0 }, jpeg))), 'INVALID');
  assert.equal(codeOf(() => decode(T.FRAME, frame({ data_len: 5 }, jpeg))), 'TRUNCATED');
  assert.equal(codeOf(() => decode(T.FRAME, frame({ data_len: 3 }, jpeg))), 'TRAILING');
  assert.equal(codeOf(() => decode(T.FRAME, frame({ format: 0 }, jpeg))), 'COUNT'); // RAW: 4 x 2 x 20 bytes

  const err = new Writer();
  err.i32(ERR.AUTH); err.u32(0xffffffff); err.u16(2000);
  assert.equal(codeOf(() => dec[T.ERROR](err.view())), 'COUNT');
  assert.equal(errName(-11), 'AUTH');
  assert.equal(errName(-99), 'CODE_-99');
  assert.equal(typeName(0x0501), 'FRAME');
  assert.equal(typeName(0x0777), '0x0777');
});

test('view helpers refuse the cameras vtc_view_* refuses', () => {
  const base = { eye: [0, 2, 10], target: [0, 2, 0], width: 64, height: 48 };
  assert.ok(viewPerspective(base));
  assert.equal(viewPerspective({ ...base, target: [0, 2, 10] }), null, 'eye == target');
  assert.equal(viewPerspective({ ...base, target: [0, 5, 10] }), null, 'up parallel to the view');
  assert.equal(viewPerspective({ ...base, fovDeg: 180 }), null);
  assert.equal(viewPerspective({ ...base, near: 0 }), null);
  assert.equal(viewPerspective({ ...base, far: 0.05 }), null);
  assert.equal(viewPerspective({ ...base, width: 0 }), null);
  assert.equal(viewOrtho({ ...base, widthM: 0, heightM: 1 }), null);
  assert.ok(viewOrtho({ ...base, widthM: 10, heightM: 5, near: -1 }));
});

/* An in-memory transport: what the Client sends is kept; the test plays
 * the server by calling t.onbytes. */
function memTransport() {
  const t = { sent: [], closed: false, onbytes: null, onclose: null };
  t.send = (b) => t.sent.push(b.slice());
  t.close = () => { t.closed = true; t.onclose && t.onclose({ reason: 'closed by the client' }); };
  return t;
}
const reply = encodeFrame;
const sentReq = (b) => new Reader(b.subarray(8, 12)).u32();

test('Client: requests by req, timeouts, pushes, throwing callbacks, close', async () => {
  const t = memTransport();
  const c = new Client(t, { timeoutMs: 200 });
  const p1 = c.ping(new Uint8Array([1]));
  const p2 = c.ping(new Uint8Array([2]));
  const [r1, r2] = t.sent.map(sentReq);
  assert.equal(r2, r1 + 1);
  // replies in one chunk, with an EVENT push between them; onevent throws
  const events = [];
  c.onevent = (ev) => { events.push(ev); throw new Error('a page bug'); };
  const uncaught = new Promise((resolve) => { c.callbackFailed = resolve; });
  const ev = reply(T.EVENT, 0, (w) => putLayout(w, LAYOUTS.event, { kind: 1, epoch: 3n, added: 2 }));
  t.onbytes(new Uint8Array([...reply(T.PONG, r2, (w) => w.u8(2)), ...ev, ...reply(T.PONG, r1, (w) => w.u8(1))]));
  assert.deepEqual([...(await p1)], [1]);
  assert.deepEqual([...(await p2)], [2]);
  assert.equal(events.length, 1);
  assert.equal(events[0].epoch, 3n);
  assert.match((await uncaught).message, /a page bug/, 'the callback\'s exception is reported, not swallowed');

  // an ERROR rejects with the server's code name and index
  const p3 = c.entityGet([5n]);
  t.onbytes(reply(T.ERROR, sentReq(t.sent.at(-1)), (w) => { w.i32(ERR.UNKNOWN_ID); w.u32(0); w.u16(3); w.bytes(new TextEncoder().encode('no!')); }));
  await assert.rejects(p3, (e) => e.codeName === 'UNKNOWN_ID' && e.index === 0 && !e.local && /no!/.test(e.message));
  const p3b = c.stats();
  t.onbytes(reply(T.ERROR, sentReq(t.sent.at(-1)), (w) => { w.i32(-99); w.u32(0xffffffff); w.u16(0); }));
  await assert.rejects(p3b, (e) => e.codeName === 'CODE_-99' && e.code === -99);

  // a reply of the wrong type rejects; so does one that does not decode
  const p4 = c.stats();
  t.onbytes(reply(T.ACK, sentReq(t.sent.at(-1)), (w) => w.zeros(12)));
  await assert.rejects(p4, (e) => e.codeName === 'TYPE' && e.local);
  const p5 = c.subscribe(1);
  t.onbytes(reply(T.ACK, sentReq(t.sent.at(-1)), (w) => w.zeros(11)));
  await assert.rejects(p5, (e) => e.codeName === 'TRUNCATED' && e.local);

  // a timeout rejects; the late reply is dropped (not taken for a push)
  const p6 = c.ping();
  await assert.rejects(p6, (e) => e.codeName === 'TIMEOUT');
  const errs = [];
  c.onerror = (e) => errs.push(e);
  t.onbytes(reply(T.PONG, sentReq(t.sent.at(-1))));
  assert.equal(errs.length, 1);
  assert.match(errs[0].message, /unexpected PONG/);

  // a request over the server's limit is refused here, not sent
  const before = t.sent.length;
  await assert.rejects(c.call(T.PING, (req) => enc.raw(T.PING, req, new Uint8Array(5000)), T.PONG),
    (e) => e.codeName === 'TOO_LARGE' && /not sent/.test(e.message));
  assert.equal(t.sent.length, before);

  // a bad header closes the connection and rejects what is pending
  const p7 = c.ping();
  const closed = new Promise((resolve) => { c.onclose = resolve; });
  const bad = reply(T.PONG, 1);
  bad[6] = 0x80;
  t.onbytes(bad);
  await assert.rejects(p7, (e) => e.codeName === 'CLOSED' && e.code === null);
  await closed;
  assert.ok(t.closed);
  await assert.rejects(c.ping(), (e) => e.codeName === 'CLOSED');
  assert.equal(errs.at(-1).codeName, 'INVALID');
});

/* A valid payload of each type the module decodes (built with its own
 * writer: the shapes, not the values, matter here). */
function validPayloads() {
  const w = (fill) => { const x = new Writer(); fill(x); return x.view().slice(); };
  const te = new TextEncoder();
  return {
    [T.HELLO_OK]: w((x) => putLayout(x, LAYOUTS.hello_ok, { version: 2 })),
    [T.ERROR]: w((x) => { x.i32(-9); x.u32(1); x.u16(5); x.bytes(te.encode('bad x')); }),
    [T.PONG]: w((x) => x.bytes(new Uint8Array([1, 2]))),
    [T.STATS_REPLY]: w((x) => putLayout(x, LAYOUTS.stats_reply, {})),
    [T.EVENT]: w((x) => putLayout(x, LAYOUTS.event, { kind: 1 })),
    [T.ACK]: w((x) => putLayout(x, LAYOUTS.ack, {})),
    [T.ENTITY_LIST_REPLY]: w((x) => { putLayout(x, LAYOUTS.list_reply, { count: 2 }); x.zeros(320); }),
    [T.VIS_RESULT]: w((x) => { putLayout(x, LAYOUTS.vis_result, { count: 3 }); x.zeros(72); }),
    [T.SUBLEVEL_IDS]: w((x) => { x.u32(2); x.u16(1); x.u16(2); }),
    [T.SUBLEVEL_LIST_REPLY]: w((x) => { x.u32(2); x.u16(1); x.u8(1); x.bytes(te.encode('a')); x.u16(2); x.u8(2); x.bytes(te.encode('bb')); }),
    [T.SUBLEVEL_INFO_REPLY]: w((x) => { x.u64(1n); x.u32(1); x.zeros(19); x.u8(3); x.bytes(te.encode('abc')); }),
    [T.DESTROYED]: w((x) => putLayout(x, LAYOUTS.destroyed, {})),
    [T.MARKED]: w((x) => { putLayout(x, LAYOUTS.marked_head, {}); putLayout(x, LAYOUTS.mark, {}); }),
    [T.SELECTED]: w((x) => { putLayout(x, LAYOUTS.selected_head, { client_id: 3, count: 2, serial: 9n }); x.u64(5n); x.u64(2n ** 63n); }),
    [T.FRAME]: w((x) => { putLayout(x, LAYOUTS.frame, { width: 2, height: 1, format: 1, data_len: 4 }); x.bytes(new Uint8Array([0xff, 0xd8, 0xff, 0xd9])); }),
    [T.ENV_REPLY]: w((x) => putLayout(x, LAYOUTS.env, {})),
  };
}

test('hostile replies: every mutation of every decoded message decodes or throws VpError, nothing else', () => {
  const rand = rng(2121);
  const payloads = validPayloads();
  assert.deepEqual(Object.keys(payloads).map(Number).sort(), Object.keys(dec).map(Number).sort(), 'a payload per decoder');
  let refused = 0, total = 0;
  for (const [type, good] of Object.entries(payloads)) {
    assert.doesNotThrow(() => decode(Number(type), good), `the valid ${typeName(Number(type))}`);
    for (let k = 0; k < 400; k++) {
      let p = good.slice();
      const op = k % 4;
      if (op === 0) p = p.subarray(0, Math.floor(rand() * p.length)); // cut short
      else if (op === 1) p = new Uint8Array([...p, ...new Uint8Array(1 + Math.floor(rand() * 40)).map(() => rand() * 256)]);
      else if (op === 2) for (let n = 0; n < 3; n++) p[Math.floor(rand() * p.length)] = Math.floor(rand() * 256);
      else if (p.length >= 4) new DataView(p.buffer).setUint32(Math.floor(rand() * (p.length - 3)), [0xffffffff, 0x80000000, 0x10000][k % 3], true);
      total++;
      try {
        decode(Number(type), p);
      } catch (e) {
        assert.ok(e instanceof VpError, `${typeName(Number(type))}: ${e}`);
        assert.ok(['TRUNCATED', 'TRAILING', 'COUNT', 'INVALID'].includes(e.codeName), e.message);
        refused++;
      }
    }
  }
  assert.ok(refused > total / 3, `${refused} of ${total} refused`);
});

test('hostile streams: a Client fed mutated replies reports errors and never throws', () => {
  const rand = rng(77);
  const good = new Uint8Array(Object.entries(validPayloads()).flatMap(([type, p]) => [...encodeFrame(Number(type), 0, (x) => x.bytes(p))]));
  for (let k = 0; k < 200; k++) {
    const s = good.slice();
    for (let n = 0; n < 1 + (k % 5); n++) s[Math.floor(rand() * s.length)] = Math.floor(rand() * 256);
    const t = memTransport();
    const c = new Client(t, { maxPayload: 1 << 20 });
    const errors = [];
    c.onerror = (e) => errors.push(e);
    c.onevent = c.onmarked = c.onselected = c.onframe = () => {};
    c.callbackFailed = (e) => assert.fail(`a callback failed: ${e}`);
    for (let at = 0; at < s.length && !c.closed;) {
      const n = 1 + Math.floor(rand() * 64);
      t.onbytes(s.subarray(at, at + n));
      at += n;
    }
    assert.ok(errors.every((e) => e instanceof VpError), String(errors.find((e) => !(e instanceof VpError))));
  }
});
