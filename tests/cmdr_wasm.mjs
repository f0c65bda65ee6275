// cmdr_wasm.mjs — the WebAssembly half of test_cmdr_wasm.c: runs the ops in
// IN through web/js/cmdr.js (its Commander class and cmdr.wasm, as a page
// does) and writes one result line an op to OUT in the format the C test
// writes from the native pad_map.c. Usage: node tests/cmdr_wasm.mjs IN OUT
//
// Numbers travel as their bits (hex) both ways: floats in, doubles out, so
// nothing is lost to decimal printing and the C compares bit patterns.
import { readFileSync, writeFileSync } from 'node:fs';
import { Commander } from '../web/js/cmdr.js';
import { Reader, getLayout, LAYOUTS, viewBytes } from '../web/js/vproto.js';

const [inPath, outPath] = process.argv.slice(2);
const dv = new DataView(new ArrayBuffer(8));
const f32 = (h) => (dv.setUint32(0, parseInt(h, 16)), dv.getFloat32(0));
const f64 = (h) => (dv.setBigUint64(0, BigInt('0x' + h)), dv.getFloat64(0));
const hex64 = (d) => (dv.setFloat64(0, d), dv.getBigUint64(0).toString(16).padStart(16, '0'));
const hexBytes = (b) => Array.from(b, (x) => x.toString(16).padStart(2, '0')).join('');
const cam = (c) => {
  const k = c.camera;
  return [...k.target, k.yaw, k.pitch, k.halfH].map(hex64).join(' ') + ` ${k.perspective ? 1 : 0} ${hex64(k.aspect)}`;
};
// a view's 160 bytes: 19 little-endian doubles (origin, view_proj), then the 8 bytes of the rest
const view = (b) => {
  if (!b) return '-';
  // the page's protocol module reads the bytes as a view and writes them back the same
  const again = viewBytes(getLayout(new Reader(b), LAYOUTS.view, 'view'));
  if (Buffer.compare(Buffer.from(again), Buffer.from(b))) throw new Error('vproto.js does not write the view back as cmdr.js gave it');
  const d = new DataView(b.buffer, b.byteOffset, b.byteLength);
  const out = [];
  for (let i = 0; i < 19; i++) out.push(d.getBigUint64(8 * i, true).toString(16).padStart(16, '0'));
  return out.join(' ') + ' t' + hexBytes(b.subarray(152));
};

// Bad values from a page, on an instance of their own: answers, never a
// trap, and the camera stays finite (the pad's numbers are clamped as the
// parsers give them).
async function hostile() {
  const h = await Commander.create();
  const check = (ok, what) => { if (!ok) throw new Error(`hostile: ${what}`); };
  const finite = () => {
    const k = h.camera;
    return [...k.target, k.yaw, k.pitch, k.halfH, k.aspect].every(Number.isFinite);
  };
  h.step({ buttons: -1, lx: NaN, ly: Infinity, rx: -Infinity, ry: 1e300, lt: -1, rt: NaN }, NaN);
  h.step({ buttons: 2 ** 40, lx: '1', ly: {}, rx: null }, 1e9);
  h.step(undefined, -5);
  check(finite(), 'non-finite pad values reached the camera');
  for (const [w, hh] of [[0, 0], [-1, 5], [NaN, 720], [5000, 10], [1.5e10, 1]]) check(h.view(w, hh) === null, `view(${w}, ${hh})`);
  for (const s of [-1, 0, NaN, Infinity]) check(h.pickView(s) === null, `pickView(${s})`);
  check(h.project([NaN, 0, 0], 1280, 720) === null, 'project(NaN)');
  check(h.project([0, 0, 0], 0, 0) === null, 'project at 0 x 0');
  check(h.rayBox([0, 0, 0], [NaN, 1, 0], [-1, -1, -1], [1, 1, 1]) === null, 'rayBox(NaN)');
  check(h.rayBox([0, 0, 0], [0, 1, 0], [-1, -1, -1], [1, Infinity, 1]) === null, 'rayBox(Infinity)');
  h.click(NaN, 5, 1280, 720), h.click(5, 5, 0, 0), h.wheel(Infinity), h.wheel(NaN), h.reset(NaN), h.reset(-3);
  check(finite(), 'the mouse made the camera non-finite');
  h.latAdd(99, 5), h.latAdd(0, NaN), h.latAdd(0, Infinity);
  check(Number.isNaN(h.latPct(99, 50)) && h.latCount(0) === 0 && Number.isNaN(h.latPct(0, 50)), 'latency rings');
  check(h.configure('x'.repeat(20000)) === 'larger than 16 KiB', 'a config over 16 KiB');
  check(/^line 1: /.test(h.configure(new Uint8Array([0xff, 0xfe, 0x3d]))), 'bytes that are not UTF-8');
  check(h.padFromGamepad(null) === null && h.padFromGamepad({ connected: false }) === null, 'no pad');
  const p = h.padFromGamepad({ buttons: [1, 0, { pressed: true }], axes: [NaN, 'x'] });
  check(p.buttons === (h.buttonBit.south | h.buttonBit.west) && p.lx === 0 && p.ly === 0 && !p.standard, 'a pad of numbers');
  check(h.padFromKeys(null) === null && h.padFromKeys(['NoSuchKey']) === null, 'no keys');
  check(h.binding('nosuch').length === 0 && h.binding(99).length === 0, 'unknown actions');
  return 'ok';
}

let c = null;
const out = [];
for (const line of readFileSync(inPath, 'utf8').split('\n')) {
  if (!line) continue;
  const [op, ...a] = line.split(' ');
  switch (op) {
    case 'I': c = await Commander.create('', { aspect: f64(a[0]) }); out.push(`I ${cam(c)}`); break;
    case 'C': {
      const err = c.configure(Buffer.from(a[0] === '-' ? '' : a[0], 'hex'));
      const binds = c.actionNames.map((_, i) => c.binding(i).map((n) => c.buttonNames.indexOf(n))
        .reduce((m, bit) => m | (1 << bit), 0) >>> 0);
      out.push(`C ${err === null ? 0 : -1} ${hex64(c.tickHz)} ${binds.join(' ')}${err === null ? '' : ' ' + err}`);
      break;
    }
    case 'S': {
      const [lx, ly, rx, ry, lt, rt] = a.slice(1, 7).map(f32);
      const r = c.step({ buttons: parseInt(a[0], 16), lx, ly, rx, ry, lt, rt }, f64(a[7]));
      out.push(`S ${r.fired} ${r.moved ? 1 : 0} ${cam(c)}`);
      break;
    }
    case 'G': {
      // a Gamepad as the browser gives it (standard mapping: buttons by
      // index, axes y down, the triggers' values) through padFromGamepad
      const mask = parseInt(a[0], 16), [a0, a1, a2, a3, v6, v7] = a.slice(1, 7).map(f32);
      const buttons = Array.from({ length: 18 }, (_, i) => {
        const pressed = (mask & (1 << i)) !== 0;
        return { pressed, touched: pressed, value: i === 6 ? v6 : i === 7 ? v7 : pressed ? 1 : 0 };
      });
      const gp = { id: 'test pad', index: 0, connected: true, mapping: 'standard', axes: [a0, a1, a2, a3], buttons };
      const r = c.step(c.padFromGamepad(gp), f64(a[7]));
      out.push(`S ${r.fired} ${r.moved ? 1 : 0} ${cam(c)}`);
      break;
    }
    case 'Y': {
      const r = c.step(c.padFromKeys(a.slice(1)), f64(a[0]));
      out.push(`S ${r.fired} ${r.moved ? 1 : 0} ${cam(c)}`);
      break;
    }
    case 'N': { const r = c.step(null, f64(a[0])); out.push(`S ${r.fired} ${r.moved ? 1 : 0} ${cam(c)}`); break; }
    case 'V': out.push(`V ${view(c.view(+a[0], +a[1]))}`); break;
    case 'P': out.push(`V ${view(c.pickView(f64(a[0])))}`); break;
    case 'R': { const r = c.ray(); out.push(`R ${[...r.eye, ...r.dir].map(hex64).join(' ')}`); break; }
    case 'J': {
      const p = c.project(a.slice(0, 3).map(f64), +a[3], +a[4]);
      out.push(`J ${p ? p.map(hex64).join(' ') : '-'}`);
      break;
    }
    case 'B': {
      const v = a.map(f64);
      const t = c.rayBox(v.slice(0, 3), v.slice(3, 6), v.slice(6, 9), v.slice(9, 12));
      out.push(`B ${t === null ? '-' : hex64(t)}`);
      break;
    }
    case 'W': c.wheel(+a[0]); out.push(`K ${cam(c)}`); break;
    case 'K': c.click(f64(a[2]), f64(a[3]), +a[0], +a[1]); out.push(`K ${cam(c)}`); break;
    case 'T': c.togglePerspective(); out.push(`K ${cam(c)}`); break;
    case 'Z': c.reset(f64(a[0])); out.push(`K ${cam(c)}`); break;
    case 'L': c.latAdd(+a[0], f64(a[1])); break;
    case 'Q': out.push(`Q ${hex64(c.latPct(+a[0], f64(a[1])))} ${c.latCount(+a[0])}`); break;
    case 'X': out.push(`X ${await hostile()}`); break;
    default: throw new Error(`cmdr_wasm.mjs: unknown op ${op}`);
  }
}
writeFileSync(outPath, out.join('\n') + '\n');
