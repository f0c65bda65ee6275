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
    default: throw new Error(`cmdr_wasm.mjs: unknown op ${op}`);
  }
}
writeFileSync(outPath, out.join('\n') + '\n');
