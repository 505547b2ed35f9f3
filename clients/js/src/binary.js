/* binary.js - BinaryClient, sdfd's binary protocol (proto/PROTOCOL.md) over one net.Socket,
 * node only (the browser entry never imports this file).
 *
 * Requests are pipelined: each gets a request id, replies are matched by it in whatever order
 * they come. At most `maxInFlight` requests are written at once (the server reads 64 per
 * connection and leaves the rest in the socket), the rest wait in a queue, and writing stops
 * whenever socket.write says its buffer is full until 'drain'. The connection is opened on
 * the first request and again on the next request after the server (or anything between)
 * closes it; each connection first sends AUTH (with a token) and HELLO, whose max_payload
 * lets an oversized request be refused here instead of costing the whole connection (the
 * server answers a frame over it by closing). Every message of this protocol only reads, so
 * a request whose connection died before its reply is sent once more on the next one; so is
 * a query a server going away refused (503 EUNAVAILABLE), once the connection has answered
 * the rest, and a new connection closed or reset before its handshake is answered (a
 * balancer handing it to a replica that is going away) is opened again, CONNECT_ATTEMPTS
 * times in all. */
import net from 'node:net';
import tls from 'node:tls';
import { SdfError } from './errors.js';
import {
  FRAMES, INTERPOLATIONS, SIGNS, WORDS, checkFilter, leBytes, leWords, modeCode, signCode,
  smoothVolume, splitWords, toPoints,
} from './wire.js';

const { HELLO, HELLO_OK, LIST_MESHES, MESHES, QUERY, VOLUME_QUERY, AUTH, AUTH_OK, RESULT, ERROR } =
  FRAMES;
const HEADER = 16;
const MAGIC = [0x53, 0x44, 0x46, 0x50]; /* "SDFP" */
/* Largest reply payloads taken before a frame is read: an ERROR holds two strings of u16
 * length; a MESHES list is 267 bytes a mesh at most. A header announcing more than its
 * request can get is a broken stream, dropped before any of it is buffered. */
const ERROR_MAX = 6 + 2 * 0xffff;
const SMALL_MAX = 16 << 20;
const KERNELS = { gaussian: 0, bump: 1 };
const VOLUMES = { sphere: 1, box: 2, mesh: 3 };
const SIGN_NAMES = Object.fromEntries(Object.entries(SIGNS).map(([k, v]) => [v, k]));
/* A new connection lost before its handshake's reply is opened this many times in all, 50
 * and 100 ms apart. */
const CONNECT_ATTEMPTS = 3;

const pad4 = (n) => (n + 3) & ~3;
const utf8 = new TextEncoder();
const text = new TextDecoder();

function nameBytes(name, what) {
  const b = utf8.encode(String(name));
  if (b.length < 1 || b.length > 255)
    throw new RangeError(`${what} must be 1-255 bytes of UTF-8, not ${b.length}`);
  return b;
}

function protocolError(why) {
  const e = new Error(`sdfd binary protocol: ${why}`);
  e.code = 'EPROTO';
  return e;
}

/* The received bytes, as the chunks the socket gave: a frame is copied out once it has all
 * arrived, into a fresh (so 4-aligned) buffer of exactly its size. */
class Incoming {
  #chunks = [];
  #head = 0;
  length = 0;

  push(chunk) {
    this.#chunks.push(chunk);
    this.length += chunk.length;
  }

  read(n) {
    const out = new Uint8Array(n);
    for (let got = 0; got < n;) {
      const c = this.#chunks[0];
      const take = Math.min(n - got, c.length - this.#head);
      out.set(c.subarray(this.#head, this.#head + take), got);
      got += take;
      this.#head += take;
      if (this.#head === c.length) {
        this.#chunks.shift();
        this.#head = 0;
      }
    }
    this.length -= n;
    return out;
  }
}

function parseError(p) {
  const v = new DataView(p.buffer, p.byteOffset, p.byteLength);
  if (p.length < 4)
    throw protocolError('ERROR frame shorter than its fields');
  const n = v.getUint16(2, true);
  if (4 + n + 2 > p.length)
    throw protocolError('ERROR frame shorter than its fields');
  const m = v.getUint16(4 + n, true);
  if (6 + n + m > p.length)
    throw protocolError('ERROR frame shorter than its fields');
  return new SdfError(v.getUint16(0, true), text.decode(p.subarray(4, 4 + n)),
    text.decode(p.subarray(6 + n, 6 + n + m)));
}

function expectType(type, want, name) {
  if (type !== want)
    throw protocolError(`expected ${name}, got message type 0x${type.toString(16)}`);
}

function parseHello(type, p) {
  expectType(type, HELLO_OK, 'HELLO_OK');
  const v = new DataView(p.buffer, p.byteOffset, p.byteLength);
  if (p.length < 14 || 14 + v.getUint16(12, true) > p.length)
    throw protocolError('HELLO_OK shorter than its fields');
  return {
    version: v.getUint16(0, true), maxPayload: v.getUint32(4, true),
    maxPoints: v.getUint32(8, true), server: text.decode(p.subarray(14, 14 + v.getUint16(12, true))),
  };
}

function parseMeshes(type, p) {
  expectType(type, MESHES, 'MESHES');
  const v = new DataView(p.buffer, p.byteOffset, p.byteLength);
  const short = () => protocolError('MESHES shorter than its entries');
  if (p.length < 4)
    throw short();
  const out = [];
  let off = 4;
  for (let i = v.getUint32(0, true); i > 0; i--) {
    if (off + 2 > p.length)
      throw short();
    const n = v.getUint16(off, true);
    if (off + 2 + n + 10 > p.length)
      throw short();
    const name = text.decode(p.subarray(off + 2, off + 2 + n));
    off += 2 + n;
    const sign = p[off + 9];
    out.push({
      name, triangles: Number(v.getBigUint64(off, true)), closed: p[off + 8] !== 0,
      sign: SIGN_NAMES[sign] ?? String(sign),
    });
    off += 10;
  }
  return out;
}

/* A RESULT for `count` points of `w` words each (PROTOCOL.md, RESULT). */
function parseResult(type, p, count, w) {
  expectType(type, RESULT, 'RESULT');
  const v = new DataView(p.buffer, p.byteOffset, p.byteLength);
  if (p.length < 8 || p[1] !== w || v.getUint32(4, true) !== count || p.length !== 8 + 4 * w * count)
    throw protocolError(`RESULT does not hold ${count} points of ${w} words`);
  return splitWords(leWords(p.subarray(8)), count, w);
}

/* The FILTER block of a filtered QUERY (PROTOCOL.md): 120 bytes, then a smoothing mesh's name
 * padded to 4. 0 in a number asks for its default, as an absent key does over HTTP. */
function filterBlock(filter) {
  const f = checkFilter(filter);
  const kernel = KERNELS[f.kernel ?? 'gaussian'];
  if (kernel === undefined || !Object.hasOwn(KERNELS, f.kernel ?? 'gaussian'))
    throw new TypeError(`unknown kernel ${JSON.stringify(f.kernel)} (known: gaussian, bump)`);
  let volume = 0, numbers = [], name = new Uint8Array(0);
  if (f.smooth) {
    const [kind, value] = smoothVolume(f.smooth);
    volume = VOLUMES[kind];
    if (kind === 'mesh')
      name = nameBytes(value, 'filter.smooth.mesh');
    else
      numbers = Array.from(value, Number);
    if (numbers.length > 6)
      throw new RangeError(`filter.smooth.${kind} has ${numbers.length} numbers`);
  }
  const block = new Uint8Array(120 + pad4(name.length));
  const v = new DataView(block.buffer);
  const u32 = (off, x, what) => {
    if (!Number.isInteger(x) || x < 0 || x > 0xffffffff)
      throw new RangeError(`filter.${what} must be an integer 0..2^32-1, not ${x}`);
    v.setUint32(off, x, true);
  };
  block[0] = kernel;
  block[1] = (f.grid ? 1 : 0) | (f.unsigned ? 2 : 0) | (f.allow_wide_bump ? 4 : 0)
    | (f.sample_gradient ? 8 : 0);
  block[2] = volume;
  block[3] = name.length;
  u32(4, f.samples ?? 0, 'samples');
  v.setFloat64(8, f.cap ?? 0, true);
  v.setFloat64(16, f.a ?? 0, true);
  v.setFloat64(24, f.b ?? 0, true);
  v.setBigUint64(32, BigInt(f.seed ?? 0), true);
  v.setFloat64(40, f.smooth?.depth ?? 0, true);
  v.setFloat64(48, f.smooth?.scale ?? 0, true);
  numbers.forEach((x, i) => v.setFloat64(56 + 8 * i, x, true));
  u32(104, f.min_samples ?? 0, 'min_samples');
  v.setFloat64(112, f.medial ?? 0, true);
  block.set(name, 120);
  return block;
}

/* A frame with its header's room in front: the payload's fixed fields from `head`, then the
 * name padded to 4, `block`, and the points. The request id goes in when it is written. */
function pointsFrame(head, name, block, points) {
  const size = 8 + pad4(name.length) + block.length + points.byteLength;
  const frame = new Uint8Array(HEADER + size);
  const v = new DataView(frame.buffer);
  frame[HEADER] = head[0];
  frame[HEADER + 1] = head[1];
  v.setUint16(HEADER + 2, name.length, true);
  v.setUint32(HEADER + 4, points.length / 3, true);
  frame.set(name, HEADER + 8);
  frame.set(block, HEADER + 8 + pad4(name.length));
  frame.set(leBytes(points), HEADER + 8 + pad4(name.length) + block.length);
  return frame;
}

function bytesFrame(payload) {
  const frame = new Uint8Array(HEADER + payload.length);
  frame.set(payload, HEADER);
  return frame;
}

export class BinaryClient {
  #host;
  #port;
  #token;
  #name;
  #window;
  #resend;
  #connectTimeout;
  #tls; /* null, or node:tls's connect options (ca, minVersion) for --bin-tls */
  #socket = null;
  #open = false; /* the handshake (AUTH, HELLO) is answered: requests may be written */
  #writable = true;
  #incoming = null;
  #frame = null; /* the header of a frame whose payload is still arriving */
  #limits = null;
  #queue = [];
  #moving = []; /* queries refused as unavailable, for the next connection once this one is done */
  #attempt = 0; /* handshakes lost in a row */
  #retryTimer = null;
  #inflight = new Map();
  #nextId = 1;
  #closed = false;
  #stats = { connects: 0, resent: 0, backpressure: 0, maxInFlight: 0 };

  /**
   * @param {{host?: string, port?: number, token?: string, clientName?: string,
   *   maxInFlight?: number, resend?: boolean, connectTimeout?: number, tls?: boolean,
   *   ca?: string | Uint8Array}} [options]
   */
  constructor(options = {}) {
    this.#host = options.host ?? '127.0.0.1';
    this.#port = options.port ?? 9090;
    this.#token = options.token;
    this.#name = options.clientName ?? 'sdfd-client.js';
    this.#window = options.maxInFlight ?? 64;
    this.#resend = options.resend ?? true;
    this.#connectTimeout = options.connectTimeout ?? 10000;
    if (options.ca !== undefined && !options.tls)
      throw new TypeError('ca is for tls: true');
    /* A server started with --bin-tls: the frames inside TLS 1.2+, its certificate verified
     * against `ca` (PEM text; node's CAs without it) and the host name. */
    this.#tls = options.tls ? { ca: options.ca, minVersion: 'TLSv1.2' } : null;
    if (!(this.#window >= 1))
      throw new RangeError('maxInFlight must be at least 1');
  }

  /** Counters: connections opened, requests re-sent after a connection died, writes that
   * filled the socket's buffer (and so waited for 'drain'), most requests in flight. */
  get stats() {
    return { ...this.#stats };
  }

  /** HELLO: {version, maxPayload, maxPoints, server}. */
  hello({ signal } = {}) {
    return this.#submit(bytesFrame(utf8.encode(this.#name)), HELLO, SMALL_MAX, parseHello, signal);
  }

  /** AUTH with the server's --token; kept for the connections opened after this one. */
  async auth(token, { signal } = {}) {
    await this.#submit(bytesFrame(utf8.encode(String(token))), AUTH, ERROR_MAX,
      (type) => expectType(type, AUTH_OK, 'AUTH_OK'), signal);
    this.#token = String(token);
  }

  /** LIST_MESHES: [{name, triangles, closed, sign}]. */
  meshes({ signal } = {}) {
    return this.#submit(bytesFrame(new Uint8Array(0)), LIST_MESHES, SMALL_MAX, parseMeshes, signal);
  }

  /** QUERY: the same result object as Client.query's. */
  async query(name, points, { mode = 'signed', sign = 'auto', filter, signal } = {}) {
    const m = modeCode(mode);
    const p = toPoints(points);
    const block = m === 4 || m === 5 ? filterBlock(filter) : new Uint8Array(0);
    const frame = pointsFrame([m, signCode(sign)], nameBytes(name, 'a mesh name'), block, p);
    const count = p.length / 3, w = WORDS[m];
    return this.#submit(frame, QUERY, Math.max(8 + 4 * w * count, ERROR_MAX),
      (type, payload) => parseResult(type, payload, count, w), signal);
  }

  /** VOLUME_QUERY: {count, distance} and with gradient: true {gradient} too; interpolation
   * "default" (code 3), "trilinear", "nearest" or "hermite" (first-order volumes only). */
  async queryVolume(name, points, { interpolation = 'default', gradient = false, signal } = {}) {
    const i = INTERPOLATIONS[interpolation];
    if (i === undefined || !Object.hasOwn(INTERPOLATIONS, interpolation))
      throw new TypeError(`interpolation must be one of ${Object.keys(INTERPOLATIONS).join(', ')}, not ${JSON.stringify(interpolation)}`);
    const p = toPoints(points);
    const frame = pointsFrame([gradient ? 1 : 0, i], nameBytes(name, 'a volume name'),
      new Uint8Array(0), p);
    const count = p.length / 3, w = gradient ? 4 : 1;
    return this.#submit(frame, VOLUME_QUERY, Math.max(8 + 4 * w * count, ERROR_MAX),
      (type, payload) => parseResult(type, payload, count, w), signal);
  }

  /** Close the connection; requests not yet answered are rejected. */
  close() {
    this.#closed = true;
    clearTimeout(this.#retryTimer);
    this.#retryTimer = null;
    const s = this.#abandon(new Error('the BinaryClient was closed'));
    if (!s || s.destroyed)
      return Promise.resolve();
    return new Promise((resolve) => {
      s.once('close', () => resolve());
      s.destroy();
    });
  }

  /* ---- requests ---- */

  /* Queue a frame (header room in front) whose reply payload is at most `expect` bytes and
   * is turned into the answer by `decode(type, payload)`. */
  #submit(frame, type, expect, decode, signal) {
    if (this.#closed)
      return Promise.reject(new Error('the BinaryClient was closed'));
    if (signal?.aborted)
      return Promise.reject(signal.reason);
    if (this.#limits && frame.length - HEADER > this.#limits.maxPayload)
      return Promise.reject(this.#tooLarge(frame));
    return new Promise((resolve, reject) => {
      const r = { frame, type, expect, decode, state: 'queued', retried: false, rid: 0 };
      const onAbort = () => {
        const queued = r.state === 'queued';
        r.finish(signal.reason);
        for (const list of queued ? [this.#queue, this.#moving] : []) {
          const i = list.indexOf(r);
          if (i >= 0)
            list.splice(i, 1);
        }
        this.#refresh();
      };
      r.finish = (err, value) => {
        if (r.state === 'done')
          return;
        r.state = 'done'; /* one still in flight stays in #inflight until its reply */
        signal?.removeEventListener('abort', onAbort);
        if (err)
          reject(err);
        else
          resolve(value);
      };
      signal?.addEventListener('abort', onAbort, { once: true });
      this.#queue.push(r);
      this.#pump();
    });
  }

  #tooLarge(frame) {
    return new RangeError(`the request's payload is ${frame.length - HEADER} bytes, over the `
      + `server's max_payload of ${this.#limits.maxPayload} (at most ${this.#limits.maxPoints} points)`);
  }

  /* Write what the window and the socket's buffer allow, connecting first if needed. */
  #pump() {
    if (this.#closed)
      return;
    if (!this.#socket) {
      if (this.#queue.length && !this.#retryTimer)
        this.#connect();
      return;
    }
    /* nothing new on a connection whose server refused a query as unavailable */
    while (this.#open && this.#writable && !this.#moving.length && this.#queue.length
      && this.#inflight.size < this.#window) {
      const r = this.#queue.shift();
      if (r.frame.length - HEADER > this.#limits.maxPayload)
        r.finish(this.#tooLarge(r.frame));
      else
        this.#write(r);
    }
    this.#refresh();
  }

  #write(r) {
    let id = this.#nextId;
    while (id === 0 || this.#inflight.has(id))
      id = (id + 1) >>> 0;
    this.#nextId = (id + 1) >>> 0;
    r.rid = id;
    r.state = 'sent';
    this.#inflight.set(id, r);
    this.#stats.maxInFlight = Math.max(this.#stats.maxInFlight, this.#inflight.size);
    const f = r.frame;
    f.set(MAGIC, 0);
    f[4] = 1;
    f[5] = r.type;
    f[6] = f[7] = 0;
    const v = new DataView(f.buffer, f.byteOffset, HEADER);
    v.setUint32(8, id, true);
    v.setUint32(12, f.length - HEADER, true);
    if (!this.#socket.write(f)) {
      this.#writable = false;
      this.#stats.backpressure++;
    }
  }

  /* An idle connection must not keep node running; one with work must. */
  #refresh() {
    const s = this.#socket;
    if (!s)
      return;
    let busy = this.#queue.length > 0 || this.#moving.length > 0;
    for (const r of this.#inflight.values())
      busy ||= r.state !== 'done';
    if (busy)
      s.ref();
    else
      s.unref();
  }

  /* ---- the connection ---- */

  #connect() {
    const where = { host: this.#host, port: this.#port };
    /* SNI carries names only; an address is checked against the certificate's IP SANs. */
    const s = this.#tls
      ? tls.connect({ ...where, ...this.#tls, servername: net.isIP(this.#host) ? undefined : this.#host })
      : net.connect(where);
    this.#socket = s;
    this.#open = false;
    this.#writable = true;
    this.#incoming = new Incoming();
    this.#frame = null;
    let failure = null;
    s.setNoDelay(true);
    s.setTimeout(this.#connectTimeout, () => {
      s.destroy(Object.assign(new Error(`no connection to ${this.#host}:${this.#port} within `
        + `${this.#connectTimeout} ms`), { code: 'ETIMEDOUT' }));
    });
    s.on(this.#tls ? 'secureConnect' : 'connect', () => {
      s.setTimeout(0);
      if (s === this.#socket)
        this.#handshake(s);
    });
    s.on('data', (chunk) => {
      if (s === this.#socket)
        this.#onData(s, chunk);
    });
    s.on('drain', () => {
      if (s === this.#socket) {
        this.#writable = true;
        this.#pump();
      }
    });
    s.on('error', (e) => {
      failure = e;
    });
    s.on('close', () => {
      if (s === this.#socket)
        this.#onClose(failure);
    });
  }

  /* AUTH (with a token) and HELLO, written ahead of the queue; requests follow once both
   * are answered. A refused AUTH fails what waits: the server closes the connection. */
  #handshake(s) {
    this.#stats.connects++;
    let waiting = 0;
    const internal = (payload, type, decode) => {
      waiting++;
      const r = { frame: bytesFrame(payload), type, expect: SMALL_MAX, decode, state: 'queued' };
      r.finish = (err, value) => {
        if (r.state === 'done' || s !== this.#socket)
          return;
        r.state = 'done';
        if (err) {
          this.#abandon(err).destroy();
          return;
        }
        if (type === HELLO)
          this.#limits = value;
        if (--waiting === 0) {
          this.#open = true;
          this.#attempt = 0;
          this.#pump();
        }
      };
      this.#write(r);
    };
    if (this.#token !== undefined)
      internal(utf8.encode(this.#token), AUTH, (type) => expectType(type, AUTH_OK, 'AUTH_OK'));
    internal(utf8.encode(this.#name), HELLO, parseHello);
    this.#refresh();
  }

  #onData(s, chunk) {
    const inc = this.#incoming;
    inc.push(chunk);
    while (s === this.#socket) {
      if (!this.#frame) {
        if (inc.length < HEADER)
          return;
        const h = inc.read(HEADER);
        const v = new DataView(h.buffer);
        if (MAGIC.some((b, i) => h[i] !== b) || h[4] !== 1)
          return this.#fatal(protocolError('a reply without the SDFP version 1 header'));
        const f = { type: h[5], rid: v.getUint32(8, true), length: v.getUint32(12, true) };
        const r = this.#inflight.get(f.rid);
        if (f.rid !== 0 && !r)
          return this.#fatal(protocolError(`a reply to request ${f.rid}, which was not sent`));
        if (f.length > (r ? r.expect : ERROR_MAX))
          return this.#fatal(protocolError(`a ${f.length}-byte reply to request ${f.rid}`));
        this.#frame = f;
      }
      if (inc.length < this.#frame.length)
        return;
      const f = this.#frame;
      this.#frame = null;
      this.#onFrame(f, inc.read(f.length));
    }
  }

  #onFrame(f, payload) {
    if (f.rid === 0) {
      /* about the connection itself (PROTOCOL.md), which the server now closes */
      let err;
      try {
        err = f.type === ERROR ? parseError(payload) : protocolError('a reply to request 0');
      } catch (e) {
        err = e;
      }
      return this.#fatal(err);
    }
    const r = this.#inflight.get(f.rid);
    this.#inflight.delete(f.rid);
    if (r.state !== 'done') {
      let err = null, value;
      try {
        if (f.type === ERROR)
          err = parseError(payload);
        else
          value = r.decode(f.type, payload);
      } catch (e) {
        err = e;
      }
      if (err && this.#mayMove(r, err)) {
        r.retried = true;
        r.state = 'queued';
        this.#moving.push(r);
        this.#stats.resent++;
      } else {
        r.finish(err, value);
      }
    }
    if (this.#moving.length && ![...this.#inflight.values()].some((x) => x.state !== 'done'))
      return this.#move();
    this.#pump();
  }

  /* A query the server refused as unavailable (a replica shutting down, or still loading)
   * goes again on the next connection, once (as one its connection took with it). */
  #mayMove(r, err) {
    return this.#resend && !r.retried && (r.type === QUERY || r.type === VOLUME_QUERY)
      && err instanceof SdfError && err.status === 503 && err.code === 'EUNAVAILABLE';
  }

  /* Every request on this connection is answered but the refused ones: they go first on a
   * new connection (to whichever replica the balancer picks). */
  #move() {
    const s = this.#drop();
    this.#queue.unshift(...this.#moving.splice(0));
    s.destroy();
    this.#pump();
  }

  /* The connection closed. One that never finished its handshake fails everything waiting
   * (the server is down, refused the token, or is not sdfd); after a working one, requests it
   * took down with it go first on the next connection, once each. */
  #onClose(failure) {
    const wasOpen = this.#open;
    const lost = [...this.#inflight.values()];
    this.#drop();
    if (!wasOpen && this.#resend && ++this.#attempt < CONNECT_ATTEMPTS
      && (!failure || failure.code === 'ECONNRESET' || failure.code === 'EPIPE')) {
      /* closed or reset before the handshake's reply: another connection may not be */
      this.#retryTimer = setTimeout(() => {
        this.#retryTimer = null;
        this.#pump();
      }, 50 << (this.#attempt - 1));
      return;
    }
    if (!wasOpen) {
      this.#attempt = 0;
      const err = failure ?? Object.assign(new Error(
        `sdfd at ${this.#host}:${this.#port} closed the connection before the handshake`),
      { code: 'ECONNRESET' });
      for (const r of lost)
        r.finish(err);
      for (const r of [...this.#moving.splice(0), ...this.#queue.splice(0)])
        r.finish(err);
      return;
    }
    const err = Object.assign(new Error(`sdfd closed the connection with the request in flight${
      failure ? `: ${failure.message}` : ''}`), { code: failure?.code ?? 'ECONNRESET', cause: failure });
    const again = [];
    for (const r of lost) {
      if (r.state === 'done')
        continue;
      if (this.#resend && !r.retried) {
        r.retried = true;
        r.state = 'queued';
        again.push(r);
        this.#stats.resent++;
      } else {
        r.finish(err);
      }
    }
    this.#queue.unshift(...this.#moving.splice(0), ...again);
    this.#pump();
  }

  /* A broken stream: nothing more on it can be trusted, so everything waiting fails. */
  #fatal(err) {
    this.#abandon(err)?.destroy();
  }

  /* Fail every request, in flight or queued, after forgetting the connection (so that no
   * failure handler acts on it); returns its socket. */
  #abandon(err) {
    const lost = [...this.#inflight.values()];
    const s = this.#drop();
    this.#attempt = 0;
    for (const r of lost)
      r.finish(err);
    for (const r of [...this.#moving.splice(0), ...this.#queue.splice(0)])
      r.finish(err);
    return s;
  }

  /* Forget the connection (its events are ignored from now on); returns its socket. */
  #drop() {
    const s = this.#socket;
    this.#socket = null;
    this.#open = false;
    this.#inflight.clear();
    this.#frame = null;
    this.#incoming = null;
    return s;
  }
}
