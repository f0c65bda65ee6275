/*
 * stream.js — what the viewer and commander pages share: the connection
 * (vproto.js over the daemon's /ws, the token from the URL fragment or a
 * login field), the frame stream drawn to a canvas (H.264 through
 * WebCodecs' VideoDecoder where the browser has it, else the daemon's
 * JPEG frames), and the measures the overlay shows and the tests collect:
 * frames a second, bit rate, decode time, and input-to-photon latency with
 * its parts.
 *
 * Latency, as `vantage commander` measures it: an input event's time ->
 * the view it changed sent (FRAME_SUBSCRIBE re-aim with the next view_seq)
 * -> the first FRAME whose view_seq is that one or later received (the
 * daemon's queue, cull, render and encode, and the network: the FRAME
 * carries render_ns and encode_ns, the rest is network and queue) ->
 * decoded (VideoDecoder's output, or the JPEG's ImageBitmap) -> drawn and
 * presented (the next animation frame after the draw).
 */
import { Client, wsTransport, ROLE, VP_FRAME_JPEG, VP_FRAME_H264, VP_EVENT_SCENE, VP_EVENT_MARKS, VP_RENDER_MOTION } from './vproto.js';

export { ROLE, VP_EVENT_SCENE, VP_EVENT_MARKS };

/* The token: the URL fragment's `token=` (never sent to a server, never
 * logged), else what the login field holds. */
export function pageToken() {
  const h = new URLSearchParams(location.hash.slice(1));
  return h.get('token') ?? '';
}

/* Options from the query string: format=jpeg forces the fallback, size=WxH,
 * fps=N, eye=X,Y,Z and at=X,Y,Z the first camera (a view to share). */
export function pageOptions() {
  const q = new URLSearchParams(location.search);
  const m = /^(\d+)x(\d+)$/.exec(q.get('size') ?? '');
  const vec = (s) => {
    const v = (q.get(s) ?? '').split(',').map(Number);
    return v.length === 3 && v.every(Number.isFinite) ? v : null;
  };
  return {
    eye: vec('eye'),
    at: vec('at'),
    forceJpeg: q.get('format') === 'jpeg',
    width: m ? +m[1] : 0,
    height: m ? +m[2] : 0,
    maxFps: Math.min(240, Math.max(1, +(q.get('fps') ?? 30) || 30)),
    /* dynamic resolution while the camera moves (VP_RENDER_MOTION); ?motion=0: every frame full size */
    motion: q.get('motion') !== '0',
  };
}

/* Connects and says HELLO; rejects with VpError (codeName AUTH for a bad token). */
export async function connect({ role, token, name }) {
  const scheme = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const c = new Client(await wsTransport(`${scheme}//${location.host}/ws`), { timeoutMs: 10000, maxPayload: 64 << 20 });
  try {
    const hello = await c.hello({ role, token, name });
    return { client: c, hello };
  } catch (e) {
    c.close();
    throw e;
  }
}

/* Which frames this browser can show: 'h264' where WebCodecs decodes
 * Constrained Baseline (a secure context: https, localhost), else 'jpeg'. */
export async function videoFormat(forceJpeg) {
  if (forceJpeg || typeof VideoDecoder === 'undefined') return 'jpeg';
  try {
    const s = await VideoDecoder.isConfigSupported({ codec: 'avc1.42E01F', optimizeForLatency: true });
    return s.supported ? 'h264' : 'jpeg';
  } catch {
    return 'jpeg';
  }
}

/* Percentiles of a list (sorted copy), p in 0..100. */
function pct(list, p) {
  if (!list.length) return NaN;
  const s = [...list].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.floor((p / 100) * s.length))];
}

const KEEP = 600; /* latency samples kept (about 20 s at 30 fps) */

/*
 * A frame stream on one canvas. aim(view, input_ms) re-aims it (the next
 * view_seq); the frames are drawn as they are decoded, latest wins (a
 * frame decoded while another waits to be drawn replaces it).
 */
export class Stream {
  constructor(client, canvas, { format = 'jpeg', maxFps = 30, quality = 0, onDrawn = null, motion = true } = {}) {
    this.client = client;
    this.motion = motion;
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.format = format;
    this.maxFps = maxFps;
    this.quality = quality;
    this.onDrawn = onDrawn;
    this.seq = 0;
    this.pending = new Map(); /* view_seq -> { input, sent } not yet seen in a frame */
    this.lat = []; /* { total, wait, net, render, encode, decode, present } ms */
    this.drawn = []; /* draw times (ms), the last second's */
    this.bytes = []; /* [time, bytes] of frames received, the last second's */
    this.decodeMs = NaN;
    this.frames = 0;
    this.keyWaits = 0; /* delta frames dropped while waiting for a key frame */
    this.last = null; /* the last frame drawn: { epoch, view_seq, visible, width, height, format } */
    this.decoder = null;
    this.needKey = true;
    this.inflight = new Map(); /* H.264 timestamp -> frame info, decoding */
    this.req = 0;
    client.onframe = (f) => this.frame(f);
  }

  /* (Re)subscribes with view (vproto.js camera) and the page's extras
   * (highlight ids, flags); input_ms: when the input that made it happened. */
  async aim(view, input = performance.now(), extra = {}) {
    const seq = (this.seq = (this.seq + 1) & 0xffff);
    const sent = performance.now();
    this.pending.set(seq, { input, sent });
    if (this.pending.size > 256) this.pending.delete(this.pending.keys().next().value);
    const fmt = this.format === 'h264' ? VP_FRAME_H264 : VP_FRAME_JPEG;
    const sub = { view, format: fmt, quality: fmt === VP_FRAME_H264 ? this.quality : this.quality || 80,
                  maxFps: this.maxFps, viewSeq: seq, ...extra,
                  flags: (extra.flags ?? 0) | (this.motion ? VP_RENDER_MOTION : 0) };
    const r = await this.client.frameSubscribe(sub);
    this.req = r.req;
    return seq;
  }

  frame(f) {
    const now = performance.now();
    this.bytes.push([now, f.data.length]);
    const info = { epoch: Number(f.epoch), view_seq: f.view_seq, visible: f.visible, width: f.width, height: f.height,
                   format: f.format, render: f.render_ns / 1e6, encode: f.encode_ns / 1e6, recv: now };
    if (f.format === VP_FRAME_H264) this.decodeH264(f, info);
    else this.decodeJpeg(f, info);
  }

  decodeJpeg(f, info) {
    /* the bytes are a view of the message: copied into the Blob */
    createImageBitmap(new Blob([f.data], { type: 'image/jpeg' })).then(
      (bmp) => this.draw(bmp, info, () => bmp.close()),
      (e) => console.warn('a JPEG frame did not decode', e));
  }

  decodeH264(f, info) {
    if (!this.decoder || this.decoder.state === 'closed') this.openDecoder();
    if (this.needKey && !f.key) {
      this.keyWaits++; /* WebCodecs refuses a delta frame first: the daemon sends a key soon */
      return;
    }
    this.needKey = false;
    const ts = this.frames++ * 1000;
    this.inflight.set(ts, info);
    /* data is copied by the chunk's constructor */
    this.decoder.decode(new EncodedVideoChunk({ type: f.key ? 'key' : 'delta', timestamp: ts, data: f.data }));
  }

  openDecoder() {
    this.decoder = new VideoDecoder({
      output: (vf) => {
        const info = this.inflight.get(vf.timestamp);
        this.inflight.delete(vf.timestamp);
        if (!info) {
          vf.close();
          return;
        }
        this.draw(vf, info, () => vf.close());
      },
      error: (e) => {
        console.warn('the H.264 decoder failed; waiting for a key frame', e);
        this.needKey = true;
        this.inflight.clear();
        this.decoder = null;
        this.onKeyNeeded?.();
      },
    });
    this.decoder.configure({ codec: 'avc1.42E01F', optimizeForLatency: true });
    this.needKey = true;
  }

  /* A decoded picture (ImageBitmap or VideoFrame) onto the canvas of the
   * frame's size: an odd size is coded one pixel larger, and that column
   * or row falls outside the canvas. (The nine-argument drawImage with a
   * VideoFrame drew half the picture squeezed in Chromium 156.) */
  draw(img, info, release) {
    const t = performance.now();
    info.decoded = t;
    const { canvas, ctx } = this;
    if (canvas.width !== info.width || canvas.height !== info.height) {
      canvas.width = info.width;
      canvas.height = info.height;
    }
    ctx.drawImage(img, 0, 0);
    release();
    this.last = info;
    this.drawnTotal = (this.drawnTotal ?? 0) + 1;
    this.drawn.push(t);
    /* presented with the next animation frame; a page not in front runs
       none, and shows nothing: its frames count as presented when drawn */
    if (document.visibilityState === 'visible') requestAnimationFrame(() => this.presented(info, performance.now()));
    else this.presented(info, t);
    this.onDrawn?.(info);
  }

  presented(info, t) {
    /* every view sent up to this frame's is now on screen */
    for (const [seq, p] of this.pending) {
      const d = (info.view_seq - seq) & 0xffff;
      if (d >= 0x8000) continue; /* a later view than this frame's */
      this.pending.delete(seq);
      const total = t - p.input;
      const recvd = info.recv - p.sent;
      this.lat.push({
        total, wait: p.sent - p.input, net: Math.max(0, recvd - info.render - info.encode), render: info.render,
        encode: info.encode, decode: info.decoded - info.recv, present: t - info.decoded,
      });
      if (this.lat.length > KEEP) this.lat.shift();
    }
    this.decodeMs = info.decoded - info.recv;
  }

  /* The overlay's figures and what the tests collect (JSON-ready). */
  stats() {
    const now = performance.now();
    while (this.drawn.length && now - this.drawn[0] > 1000) this.drawn.shift();
    while (this.bytes.length && now - this.bytes[0][0] > 1000) this.bytes.shift();
    const part = (k) => this.lat.map((l) => l[k]);
    const totals = part('total');
    const hist = new Array(20).fill(0); /* 5 ms buckets to 100 ms, the last open */
    for (const v of totals) hist[Math.min(19, Math.floor(v / 5))]++;
    const parts = {};
    for (const k of ['wait', 'net', 'render', 'encode', 'decode', 'present']) parts[k] = pct(part(k), 50);
    return {
      format: this.format, fps: this.drawn.length, kbps: this.bytes.reduce((a, b) => a + b[1], 0) * 8 / 1000,
      decode_ms: this.decodeMs, frames: this.frames, drawn_total: this.drawnTotal ?? 0, key_waits: this.keyWaits,
      samples: totals.length,
      p50: pct(totals, 50), p95: pct(totals, 95), parts_p50: parts, hist, last: this.last,
    };
  }
}

/* The overlay (#stats, #hist) from the stream's stats, with the page's own
 * line: a page calls it every animation frame, it redraws four times a
 * second (stats() sorts the latency samples). */
let shownAt = 0;
export function showStats(stream, extra = (s) => '') {
  const now = performance.now();
  if (!stream || now - shownAt < 250) return;
  shownAt = now;
  const s = stream.stats();
  document.getElementById('stats').textContent = statsText(s, extra(s));
  drawHist(document.getElementById('hist'), s.hist);
}

/* A small overlay text block for the stats (the pages' corner). */
function statsText(s, extra = '') {
  const f = (v, d = 1) => (Number.isFinite(v) ? v.toFixed(d) : '-');
  const p = s.parts_p50;
  return `${s.format.toUpperCase()}  ${s.fps} fps  ${f(s.kbps / 1000, 2)} Mbit/s  decode ${f(s.decode_ms)} ms\n` +
    `input→photon p50 ${f(s.p50)} p95 ${f(s.p95)} ms (${s.samples})\n` +
    `  wait ${f(p.wait)} net ${f(p.net)} render ${f(p.render)} encode ${f(p.encode)} decode ${f(p.decode)} present ${f(p.present)}` +
    (extra ? `\n${extra}` : '');
}

/* The histogram as bars on a small canvas. */
function drawHist(canvas, hist) {
  const g = canvas.getContext('2d');
  const w = canvas.width, h = canvas.height, n = hist.length, top = Math.max(1, ...hist);
  g.clearRect(0, 0, w, h);
  g.fillStyle = '#7fd1ff';
  hist.forEach((v, i) => {
    const bh = Math.round((v / top) * (h - 2));
    g.fillRect(Math.floor((i * w) / n) + 1, h - bh, Math.floor(w / n) - 2, bh);
  });
}

/* Connects as role, asking for a token in the page's login form (#login,
 * #token, #login-why) while the daemon refuses it: resolves with the
 * client, or null after another failure (say() told why; the caller
 * retries). */
export async function connectAsking({ role, name, roleName }, say) {
  const $ = (id) => document.getElementById(id);
  let token = pageToken();
  for (;;) {
    try {
      say('connecting');
      return (await connect({ role, token, name })).client;
    } catch (e) {
      if (e.codeName !== 'AUTH') {
        say(`cannot connect: ${e.message}`);
        return null;
      }
      token = await askToken($('login'), $('token'), $('login-why'), `This daemon needs a ${roleName} token.`);
    }
  }
}

/* A login prompt when the token is refused: resolves with the new token. */
function askToken(form, input, message, why) {
  message.textContent = why;
  form.hidden = false;
  input.focus();
  return new Promise((resolve) => {
    form.onsubmit = (ev) => {
      ev.preventDefault();
      form.hidden = true;
      resolve(input.value);
    };
  });
}
