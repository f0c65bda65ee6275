/*
 * scene.test.mjs — what a viewer and a commander read and do, through
 * vproto.js against the real vantaged, with the C CLI `vantage` as the
 * independent model: an entity the CLI adds is what ENTITY_GET returns and
 * arrives as an EVENT; a camera gives the CLI's VIS_QUERY bytes exactly
 * (recorded by a proxy) and the same visible ids; sub-level names and
 * lists agree; MARK is pushed as MARKED to another client, SELECT as
 * SELECTED (and the CLI's watch sees it); DESTROY is what the CLI then sees.
 */
import test from 'node:test';
import assert from 'node:assert/strict';
import { startDaemon, connect, cli, jsonLines, recordingProxy, waitFor } from './harness.mjs';
import {
  ROLE, T, enc, FrameParser, viewPerspective, viewOrtho, viewBytes, VP_EVENT_SCENE, VP_EVENT_MARKS, VP_EVENT_SELECTION,
  VP_ENT_DYNAMIC,
} from '../../web/js/vproto.js';

let d;
test.before(async () => { d = await startDaemon(); });
test.after(async () => { await d.stop(); });

/* "added id 5 handle 4194304 at epoch 1" -> { handle, epoch } */
async function cliAdd(args) {
  const r = await cli(d, ['add', ...args]);
  assert.equal(r.code, 0, r.stderr);
  const m = /added id \d+ handle (\d+) at epoch (\d+)/.exec(r.stdout);
  assert.ok(m, r.stdout);
  return { handle: Number(m[1]), epoch: BigInt(m[2]) };
}

test('an entity the CLI adds: ENTITY_GET has the CLI\'s fields, and SUBSCRIBE pushed its EVENT', async () => {
  const c = await connect(d, ROLE.VIEWER);
  const ack = await c.subscribe(VP_EVENT_SCENE);
  const event = waitFor(c, 'onevent');
  const a = await cliAdd(['101', '1.5,2,-30', '3', '--class', '7', '--sublevel', '2', '--dynamic', '--aabb', '-1,-0.5,-33,4,5.25,-27']);
  const ev = await event;
  assert.equal(ev.kind, 1);
  assert.equal(ev.epoch, a.epoch);
  assert.ok(ev.epoch > ack.epoch);
  assert.equal(ev.added, 1);
  assert.equal(ev.updated + ev.removed, 0);
  await cliAdd(['102', '-20,0,-60', '1']);
  // the id above 2^53 needs BigInt on both sides
  await cliAdd(['0x8000000100000005', '0,0,-90', '2']);

  const ids = [101n, 102n, 0x8000000100000005n];
  const got = await c.entityGet(ids);
  const want = jsonLines((await cli(d, ['get', ...ids.map(String)])).stdout);
  assert.equal(got.entities.length, 3);
  got.entities.forEach((e, i) => {
    const w = want[i];
    assert.equal(e.id, w.id);
    assert.equal(e.handle, w.handle);
    assert.equal(e.class_id, w.class);
    assert.equal(e.sublevel, w.sublevel);
    assert.equal(Boolean(e.flags & VP_ENT_DYNAMIC), w.dynamic);
    assert.deepEqual(e.sphere, w.sphere);
    assert.deepEqual(e.aabb, w.aabb);
  });
  assert.equal(got.entities[0].handle, (await c.entityGet([101n])).entities[0].handle);
  c.close();
});

test('VIS_QUERY: the camera is the CLI\'s bytes, and the visible ids are the CLI\'s', async () => {
  for (const [id, pos, r] of [[201, '0,1,-10', 1], [202, '8,1,-25', 2], [203, '0,1,40', 1], [204, '200,1,-20', 1], [205, '-3,6,-15', 0.5]])
    await cliAdd([String(id), pos, String(r)]);
  const cam = { eye: [3.5, 4.25, 20], target: [-1, 1.5, -7], up: [0, 1, 0], fovDeg: 50, width: 640, height: 360, near: 0.5, far: 500 };
  const args = ['query', '--eye', cam.eye.join(','), '--at', cam.target.join(','), '--fov', '50', '--size', '640x360',
    '--near', '0.5', '--far', '500', '--json'];
  const proxy = await recordingProxy(d);
  const r = await cli({ port: proxy.port }, args);
  await proxy.close();
  assert.equal(r.code, 0, r.stderr);
  // the CLI's VIS_QUERY, as it went on the wire
  const up = new FrameParser().push(Buffer.concat(proxy.conns[0].up));
  const q = up.find((f) => f.type === T.VIS_QUERY);
  assert.ok(q, 'the CLI sent a VIS_QUERY');
  const view = viewPerspective(cam);
  const mine = enc.visQuery(q.req, [view]);
  assert.equal(Buffer.from(mine.subarray(12)).toString('hex'), Buffer.from(q.payload).toString('hex'), 'the same 168 bytes');
  assert.equal(Buffer.from(viewBytes(view)).toString('hex'), Buffer.from(q.payload.subarray(8, 168)).toString('hex'));

  const lines = jsonLines(r.stdout);
  const summary = lines.pop();
  const c = await connect(d, ROLE.VIEWER);
  const res = await c.visQuery([view]);
  assert.equal(res.epoch, BigInt(summary.epoch));
  assert.equal(res.visible, summary.visible);
  assert.equal(res.tested, summary.tested);
  const sortIds = (a) => [...a].sort((x, y) => (x < y ? -1 : x > y ? 1 : 0));
  assert.deepEqual(sortIds(res.records.map((x) => x.id)), sortIds(lines.map((x) => x.id)));
  const seen = new Set(res.records.map((x) => x.id));
  // what the scene was built to show: in front (201, 202, 205) seen; behind (203) and far aside (204) not
  for (const id of [201n, 202n, 205n]) assert.ok(seen.has(id), `${id} visible`);
  for (const id of [203n, 204n]) assert.ok(!seen.has(id), `${id} not visible`);
  c.close();
});

test('VIS_QUERY of an orthographic (top-down) camera: the CLI\'s --ortho bytes and ids', async () => {
  const cam = { eye: [1, 80, -15], target: [1, 0, -15], up: [0, 0, -1], widthM: 60, heightM: 40, width: 300, height: 200, near: 1, far: 200 };
  const proxy = await recordingProxy(d);
  const r = await cli({ port: proxy.port }, ['query', '--eye', cam.eye.join(','), '--at', cam.target.join(','), '--up', '0,0,-1',
    '--ortho', '60,40', '--size', '300x200', '--near', '1', '--far', '200', '--json']);
  await proxy.close();
  assert.equal(r.code, 0, r.stderr);
  const q = new FrameParser().push(Buffer.concat(proxy.conns[0].up)).find((f) => f.type === T.VIS_QUERY);
  const view = viewOrtho(cam);
  assert.equal(Buffer.from(enc.visQuery(q.req, [view]).subarray(12)).toString('hex'), Buffer.from(q.payload).toString('hex'));
  const c = await connect(d, ROLE.VIEWER);
  const res = await c.visQuery([view]);
  const lines = jsonLines(r.stdout);
  lines.pop();
  assert.deepEqual(res.records.map((x) => x.id).sort(), lines.map((x) => x.id).sort());
  assert.ok(res.records.length >= 2, 'the top-down box covers entities 201 and 205 at least');
  c.close();
});

test('sub-levels: SUBLEVEL_NAMES defines what the CLI lists; SUBLEVEL_LIST and SUBLEVEL_INFO agree with it', async () => {
  const ed = await connect(d, ROLE.EDITOR);
  const ids = await ed.sublevelNames(['north', 'south', 'north']);
  assert.equal(ids[0], ids[2]);
  assert.notEqual(ids[0], ids[1]);
  // an entity in "north", by the CLI's importer (which names sub-levels too)
  const imp = await cli(d, ['import', '-'], { input: '{"id": 401, "sphere": [0,0,-20,1], "sublevel": "north"}\n' });
  assert.equal(imp.code, 0, imp.stderr);
  const v = await connect(d, ROLE.VIEWER);
  const list = await v.sublevelList();
  const byName = Object.fromEntries(list.map((s) => [s.name, s.id]));
  assert.equal(byName.north, ids[0]);
  assert.equal(byName.south, ids[1]);
  const want = jsonLines((await cli(d, ['sublevel', 'list', '--json'])).stdout);
  const info = await v.sublevelInfo();
  assert.deepEqual(
    info.sublevels.map((s) => ({ id: s.id, name: s.name, state: s.stateName, entities: s.entities })),
    want.map((s) => ({ id: Number(s.id), name: s.name, state: s.state, entities: s.entities })));
  assert.equal(info.epoch, BigInt(want[0].epoch));
  assert.equal(info.sublevels.find((s) => s.name === 'north').entities, 1);
  ed.close();
  v.close();
});

test('MARK is pushed as MARKED to a second client; the CLI\'s MARK too', async () => {
  const a = await connect(d, ROLE.COMMANDER);
  const b = await connect(d, ROLE.COMMANDER);
  await a.subscribe(VP_EVENT_MARKS);
  const pushed = waitFor(a, 'onmarked');
  const mark = { pos: [12.5, 0.25, -40], entity: 201n, kind: 1, ttl_ms: 1500 };
  const ack = await b.mark(mark);
  assert.equal(ack.count, 1, 'sent to the one subscriber');
  const m = await pushed;
  assert.equal(m.client_id, b.helloOk.client_id);
  assert.deepEqual(m.mark, mark);
  // the CLI as the sender
  const fromCli = waitFor(a, 'onmarked');
  const r = await cli(d, ['mark', '-7,1,3', '--kind', '0', '--ttl', '900']);
  assert.equal(r.code, 0, r.stderr);
  assert.match(r.stdout, /sent to 1 subscriber$/m);
  const m2 = await fromCli;
  assert.deepEqual(m2.mark, { pos: [-7, 1, 3], entity: 0n, kind: 0, ttl_ms: 900 });
  assert.notEqual(m2.client_id, b.helloOk.client_id);
  // bad marks: the daemon's checks, by code name
  assert.equal((await b.mark({ pos: [0, 0, 0], ttl_ms: 0 }).catch((e) => e)).codeName, 'INVALID');
  assert.equal((await b.mark({ pos: [Infinity, 0, 0] }).catch((e) => e)).codeName, 'NONFINITE');
  a.close();
  b.close();
});

test('SELECT: the selection where it stands on subscribing, then each change; the CLI sets and watches it', async () => {
  const a = await connect(d, ROLE.VIEWER);
  const b = await connect(d, ROLE.COMMANDER);
  const got = [];
  a.onselected = (s) => got.push(s);
  const next = async (n) => { while (got.length < n) await new Promise((r) => setTimeout(r, 20)); return got[n - 1]; };
  await a.subscribe(VP_EVENT_SELECTION);
  const first = await next(1);
  // the CLI's watch, an independent reader of the same pushes: SELECT until
  // it went to both subscribers (the watch has subscribed by then)
  const watch = cli(d, ['watch', '--selection', '--count', '2']);
  const ids = [201n, 2n ** 63n + 5n];
  let ack, sent = 0;
  do {
    await new Promise((r) => setTimeout(r, 100));
    ack = await b.select(ids);
    sent++;
  } while (ack.count < 2);
  assert.equal(ack.count, 2, 'the page and the CLI');
  const s = await next(1 + sent); // each went to the page
  assert.equal(s.client_id, b.helloOk.client_id);
  assert.ok(s.serial > first.serial);
  assert.deepEqual(s.ids, ids);
  const w = await watch;
  assert.equal(w.code, 0, w.stderr);
  const lines = w.stdout.trim().split('\n');
  assert.equal(lines.length, 2);
  // the CLI prints ids as exact decimals: compare as text
  assert.equal(lines[1], `{"serial": ${s.serial}, "client": ${s.client_id}, "ids": [201, 9223372036854775813]}`);
  // the CLI's SELECT reaches the page
  const n = got.length;
  const r = await cli(d, ['select', '7,8']);
  assert.equal(r.code, 0, r.stderr);
  assert.deepEqual((await next(n + 1)).ids, [7n, 8n]);
  // refused: a viewer, an id 0, an id twice (nothing pushed, nothing changed)
  assert.equal((await a.select([1n]).catch((e) => e)).codeName, 'AUTH');
  assert.equal((await b.select([3n, 0n]).catch((e) => e)).codeName, 'INVALID');
  assert.equal((await b.select([3n, 3n]).catch((e) => e)).codeName, 'DUPLICATE');
  await b.select([]);
  const cleared = await next(n + 2);
  assert.equal(cleared.count, 0);
  assert.equal(cleared.serial, got[n].serial + 1n, 'the refused ones changed nothing');
  a.close();
  b.close();
});

test('DESTROY from a commander: DESTROYED, and the CLI sees the sphere and the debris', async () => {
  const a = await cliAdd(['301', '1,2,-30', '3']);
  const c = await connect(d, ROLE.COMMANDER);
  const out = await c.destroy({ id: 301n, handle: a.handle, debris: 2, center: [1, 2, -30], radius: 1 });
  assert.equal(out.spheres, 1);
  assert.equal(out.debris, 2);
  assert.ok(out.epoch > a.epoch);
  // the CLI's own DESTROY of the entity finds JS's sphere in its set
  const r = await cli(d, ['destroy', '301', '1,2,-30', '1', '--json']);
  assert.equal(r.code, 0, r.stderr);
  const w = jsonLines(r.stdout)[0];
  assert.equal(w.spheres, 2);
  assert.equal(BigInt(w.epoch), out.epoch + 1n);
  // the debris are entities now: ids 2^62 + n (PROTOCOL.md), and the CLI gets them
  const g = await cli(d, ['get', String(2n ** 62n), String(2n ** 62n + 1n)]);
  assert.equal(g.code, 0, g.stderr);
  assert.equal(jsonLines(g.stdout).length, 2);
  // refusals by name: a stale handle, a sphere that misses the entity
  assert.equal((await c.destroy({ id: 301n, handle: a.handle + 1, center: [1, 2, -30], radius: 1 }).catch((e) => e)).codeName, 'STALE');
  const miss = await c.destroy({ id: 301n, center: [1, 2, 900], radius: 1 }).catch((e) => e);
  assert.equal(miss.codeName, 'INVALID');
  assert.match(miss.message, /does not touch entity 301/);
  c.close();
});

test('ENV_GET: the environment the CLI set and prints', async () => {
  const r = await cli(d, ['env', '--night']);
  assert.equal(r.code, 0, r.stderr);
  const c = await connect(d, ROLE.VIEWER);
  const e = await c.envGet();
  // the CLI prints with %g: 6 significant digits of the f32 values
  const g = (x) => Number(x.toPrecision(6));
  const nums = (line) => line.match(/-?[\d.]+(?:e[-+]?\d+)?/g).map(Number);
  const lines = Object.fromEntries(r.stdout.trim().split('\n').map((l) => [l.split(':')[0], l.slice(l.indexOf(':') + 1)]));
  assert.deepEqual(nums(lines.sky), [...e.sky_color, e.sky_intensity].map(g), 'sky: color:R,G,B, intensity');
  assert.equal(e.sky_mode, 0);
  assert.deepEqual(nums(lines.ground), [e.ground_height, ...e.ground_color].map(g));
  assert.deepEqual(nums(lines.fog), [e.fog_density, ...e.fog_color, e.fog_height_falloff].map(g));
  assert.equal(e.exposure_mode, 1);
  assert.deepEqual(nums(lines.exposure), [e.exposure_comp].map(g));
  assert.equal(nums(lines.sun)[2], g(e.sun_lux));
  assert.deepEqual(nums(lines.sun).slice(3), e.sun_color.map(g));
  c.close();
});
