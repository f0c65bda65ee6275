/*
 * frames.test.mjs — pictures through vproto.js from the real vantaged:
 * RENDER of a camera sends the CLI's bytes and gets the CLI's JPEG byte
 * for byte (the renderer is deterministic); FRAME_SUBSCRIBE with JPEG
 * pushes a JPEG of the asked size (its SOF read here), a CLI edit brings
 * a new frame at the CLI's epoch, a re-aimed view's view_seq comes back,
 * and bad subscriptions get the daemon's ERROR. Frames are small (96 x 64)
 * so the software renderer takes a few ms each.
 */
import test from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync, rmSync } from 'node:fs';
import path from 'node:path';
import { startDaemon, connect, cli, recordingProxy, waitFor } from './harness.mjs';
import { ROLE, T, enc, FrameParser, viewPerspective, VP_FRAME_JPEG } from '../../web/js/vproto.js';

let d;
test.before(async () => {
  d = await startDaemon();
  for (const [id, pos, r] of [[1, '0,1,-10', 2], [2, '5,1,-20', 3], [3, '-6,2,-14', 1.5]]) {
    const a = await cli(d, ['add', String(id), pos, String(r)]);
    assert.equal(a.code, 0, a.stderr);
  }
});
test.after(async () => { await d.stop(); });

/* A JPEG's size from its SOF segment, walking the markers (the
 * independent reading of the bytes: FF D8, segments, SOF0..SOF15 but
 * DHT/JPG/DAC hold height and width at +5 and +7). */
function jpegSize(b) {
  assert.equal(b[0], 0xff);
  assert.equal(b[1], 0xd8, 'SOI');
  assert.equal(b[b.length - 2], 0xff);
  assert.equal(b[b.length - 1], 0xd9, 'EOI');
  for (let i = 2; i + 4 <= b.length;) {
    assert.equal(b[i], 0xff, `a marker at ${i}`);
    const m = b[i + 1], len = (b[i + 2] << 8) | b[i + 3];
    if (m >= 0xc0 && m <= 0xcf && m !== 0xc4 && m !== 0xc8 && m !== 0xcc)
      return { height: (b[i + 5] << 8) | b[i + 6], width: (b[i + 7] << 8) | b[i + 8] };
    assert.notEqual(m, 0xda, 'SOS before any SOF');
    i += 2 + len;
  }
  return assert.fail('no SOF');
}

const cam = { eye: [2, 6, 12], target: [0, 1, -12], width: 96, height: 64 };

test('RENDER: the CLI\'s request bytes and the CLI\'s JPEG, byte for byte', async () => {
  const file = path.join(d.dataDir, 'cli.jpg');
  const proxy = await recordingProxy(d);
  const r = await cli({ port: proxy.port }, ['render', '--eye', cam.eye.join(','), '--at', cam.target.join(','),
    '--size', '96x64', '-o', file]);
  await proxy.close();
  assert.equal(r.code, 0, r.stderr);
  const q = new FrameParser().push(Buffer.concat(proxy.conns[0].up)).find((f) => f.type === T.RENDER);
  assert.ok(q, 'the CLI sent a RENDER');
  const view = viewPerspective(cam);
  const m = { view, format: VP_FRAME_JPEG, quality: 85 };
  assert.equal(Buffer.from(enc.render(q.req, m).subarray(12)).toString('hex'), Buffer.from(q.payload).toString('hex'));

  const c = await connect(d, ROLE.VIEWER);
  const f = await c.render(m);
  assert.equal(f.width, 96);
  assert.equal(f.height, 64);
  assert.equal(f.view_seq, 0);
  assert.equal(f.visible, 3);
  assert.deepEqual(jpegSize(f.data), { width: 96, height: 64 });
  assert.ok(Buffer.from(f.data).equals(readFileSync(file)), 'the same JPEG file');
  rmSync(file);
  c.close();
});

test('FRAME_SUBSCRIBE (JPEG): frames of the asked size; an edit brings a new epoch; a re-aim its view_seq', async () => {
  const c = await connect(d, ROLE.VIEWER);
  const first = waitFor(c, 'onframe');
  const sub = await c.frameSubscribe({ view: viewPerspective(cam), format: VP_FRAME_JPEG, quality: 70, maxFps: 60, viewSeq: 7 });
  const [f1, req1] = await first;
  assert.equal(req1, sub.req, 'frames carry the subscription\'s req');
  assert.equal(f1.view_seq, 7);
  assert.equal(f1.format, VP_FRAME_JPEG);
  assert.deepEqual([f1.width, f1.height], [96, 64]);
  assert.deepEqual(jpegSize(f1.data), { width: 96, height: 64 });
  assert.equal(f1.epoch, sub.ack.epoch);
  // the picture is a view of the received bytes, past the 32-byte FRAME header
  assert.ok(f1.data.byteOffset >= 32 && f1.data.buffer.byteLength >= f1.data.length + 32);

  // another client's edit: a new frame, at the CLI's epoch
  const next = waitFor(c, 'onframe', (f) => f.epoch > f1.epoch);
  const a = await cli(d, ['add', '4', '2,1,-8', '1']);
  assert.equal(a.code, 0, a.stderr);
  const epoch = BigInt(/at epoch (\d+)/.exec(a.stdout)[1]);
  const [f2] = await next;
  assert.equal(f2.epoch, epoch);
  assert.equal(f2.visible, 4);
  assert.equal(f2.view_seq, 7);

  // re-aimed: the new view_seq comes back (frames of the old view may come first)
  const aimed = waitFor(c, 'onframe', (f) => f.view_seq === 8);
  const sub2 = await c.frameSubscribe({ view: viewPerspective({ ...cam, eye: [-4, 6, 12] }), quality: 70, maxFps: 60, viewSeq: 8 });
  const [f3, req3] = await aimed;
  assert.equal(req3, sub2.req);
  assert.deepEqual(jpegSize(f3.data), { width: 96, height: 64 });
  assert.ok(!Buffer.from(f3.data).equals(Buffer.from(f2.data)), 'another camera, another picture');

  const ack = await c.frameUnsubscribe();
  assert.equal(ack.epoch, epoch);
  c.close();
});

test('bad subscriptions get the daemon\'s ERROR by code name; nothing is subscribed', async () => {
  const c = await connect(d, ROLE.VIEWER);
  let frames = 0;
  c.onframe = () => { frames++; };
  const view = viewPerspective(cam);
  const code = (m) => c.frameSubscribe(m).then(() => 'OK', (e) => e);
  let e = await code({ view: { ...view, view_proj: new Array(16).fill(0) } });
  assert.equal(e.codeName, 'MATRIX');
  assert.equal(e.index, 0xffffffff, 'the one view of a stream: no index');
  assert.equal((await code({ view, quality: 0 })).codeName, 'INVALID');
  assert.equal((await code({ view, maxFps: 0 })).codeName, 'INVALID');
  assert.equal((await code({ view, maxFps: 241 })).codeName, 'INVALID');
  assert.equal((await code({ view, format: 9 })).codeName, 'INVALID');
  e = await code({ view: { ...view, viewport_w: 5000, viewport_h: 5000 } });
  assert.equal(e.codeName, 'LIMIT');
  await c.ping(); // a round trip: any frame would have come before its PONG
  assert.equal(frames, 0);
  c.close();
});
