/* http.js - Client, sdfd's HTTP API (docs/api.md) over fetch alone, so the same module runs
 * in node 18+ and in a browser. Points go out as Float32Arrays in the chosen body form and
 * answers come back as Float32Arrays, bit for bit what the server computed; refusals are
 * SdfError with the server's status, code and message. */
import { SdfError } from './errors.js';
import {
  CLOSEST_DESCR, WORDS, checkFilter, encodeNpy, leBytes, leWords, modeCode, parseNpy,
  signCode, smoothVolume, splitWords, toOps, toPoints,
} from './wire.js';

const TYPES = { json: 'application/json', octet: 'application/octet-stream', npy: 'application/x-npy' };
const VOLUME_MODES = { value: 1, gradient: 4 };

function formType(form, what) {
  const t = TYPES[form];
  if (!t || !Object.hasOwn(TYPES, form))
    throw new TypeError(`${what} must be "json", "octet" or "npy", not ${JSON.stringify(form)}`);
  return t;
}

/* A name in a path: %-encoded, so that a name with '/' or '?' reaches the server as the bad
 * name it is instead of another route. */
const seg = (name) => encodeURIComponent(String(name));

/** The filter parameters as URL arguments (docs/api.md): booleans 1/0, the smoothing volume
 * as smooth_sphere / smooth_box / smooth_mesh plus smooth_depth and smooth_scale. */
function filterArgs(filter, args) {
  for (const [k, v] of Object.entries(filter)) {
    if (k === 'smooth')
      continue;
    args.set(k, typeof v === 'boolean' ? (v ? '1' : '0') : String(v));
  }
  if (filter.smooth) {
    const [kind, value] = smoothVolume(filter.smooth);
    args.set(`smooth_${kind}`, kind === 'mesh' ? String(value) : Array.from(value, String).join(','));
    for (const k of ['depth', 'scale']) {
      if (filter.smooth[k] !== undefined)
        args.set(`smooth_${k}`, String(filter.smooth[k]));
    }
  }
}

/* JSON text of the coordinates. A -0 stays -0.0 (JSON.stringify would print 0); JSON has no
 * NaN or Infinity, so those are refused here rather than sent as something else. */
function jsonCoordinates(p) {
  const parts = new Array(p.length);
  for (let i = 0; i < p.length; i++) {
    const v = p[i];
    if (!Number.isFinite(v))
      throw new RangeError(`point ${Math.floor(i / 3)} has a coordinate ${v}, which JSON cannot carry (the octet and npy forms let the server judge it)`);
    parts[i] = Object.is(v, -0) ? '-0.0' : String(v);
  }
  return `[${parts.join(',')}]`;
}

/* A JSON answer's arrays as typed arrays: "distance" and, where present, "gradient" and
 * "closest" (triples, flattened) and "triangle". */
function fromJson(r, count) {
  const out = { count, distance: Float32Array.from(r.distance) };
  for (const k of ['gradient', 'closest']) {
    if (r[k])
      out[k] = Float32Array.from(r[k].flat());
  }
  if (r.triangle)
    out.triangle = Uint32Array.from(r.triangle);
  if (out.distance.length !== count)
    throw new RangeError(`the answer holds ${out.distance.length} values for ${count} points`);
  return out;
}

/* An npy answer (docs/api.md, Responses): (N,) or (N, W) float32, or closest's structured
 * (N,) array, whose records are the octet form's five words. */
function npyWords(bytes, count, w, closest) {
  const a = parseNpy(bytes);
  const want = closest ? CLOSEST_DESCR : '<f4';
  const shapeOk = w === 1 || closest ? a.shape.length === 1 && a.shape[0] === count
    : a.shape.length === 2 && a.shape[0] === count && a.shape[1] === w;
  if (a.descr !== want || !shapeOk || a.fortranOrder)
    throw new RangeError(`unexpected npy answer ${a.descr} (${a.shape}) for ${count} x ${w} words`);
  return leWords(a.data.subarray(0, 4 * count * w));
}

async function errorFrom(res) {
  const text = await res.text();
  try {
    const e = JSON.parse(text).error;
    if (typeof e.code === 'string')
      return new SdfError(res.status, e.code, String(e.message));
  } catch {
    /* not sdfd's JSON error: report the body as it came */
  }
  return new SdfError(res.status, 'EUNKNOWN', text.slice(0, 200));
}

function sleep(ms, signal) {
  return new Promise((resolve, reject) => {
    if (signal?.aborted)
      return reject(signal.reason);
    const onAbort = () => {
      clearTimeout(timer);
      reject(signal.reason);
    };
    const timer = setTimeout(() => {
      signal?.removeEventListener('abort', onAbort);
      resolve();
    }, ms);
    signal?.addEventListener('abort', onAbort, { once: true });
  });
}

/* The arrays of a binary little-endian PLY as sdfd writes it: float x y z, then faces of
 * one count byte and three uint32 indices. */
function plyArrays(bytes) {
  const text = new TextDecoder('latin1').decode(bytes.subarray(0, Math.min(bytes.length, 1024)));
  const end = text.indexOf('end_header\n') + 'end_header\n'.length;
  const count = (what) => Number(new RegExp(`element ${what} (\\d+)`).exec(text)[1]);
  const nv = count('vertex'), nt = count('face');
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const vertices = new Float32Array(3 * nv), triangles = new Uint32Array(3 * nt);
  for (let i = 0; i < 3 * nv; i++)
    vertices[i] = view.getFloat32(end + 4 * i, true);
  for (let t = 0, at = end + 12 * nv; t < nt; t++, at += 13)
    for (let c = 0; c < 3; c++)
      triangles[3 * t + c] = view.getUint32(at + 1 + 4 * c, true);
  return { vertices, triangles };
}

export class Client {
  #base;
  #token;
  #fetch;
  #headers;

  /**
   * @param {string} [url] sdfd's HTTP address, e.g. "http://127.0.0.1:8080"
   * @param {{token?: string, fetch?: typeof fetch, headers?: Record<string, string>}} [options]
   */
  constructor(url = 'http://127.0.0.1:8080', options = {}) {
    this.#base = String(url).replace(/\/+$/, '');
    this.#token = options.token;
    this.#fetch = options.fetch ?? globalThis.fetch.bind(globalThis);
    this.#headers = { ...(options.headers ?? {}) };
  }

  get url() {
    return this.#base;
  }

  /* One request; a non-2xx status (other than those in `pass`) is an SdfError. A request
   * whose connection failed is sent once more where that does no harm: everything but a
   * bake, which would start a second job when only its answer was lost. */
  async #request(method, path, { body, type, accept, signal, pass = [] } = {}) {
    const headers = { ...this.#headers };
    if (type)
      headers['Content-Type'] = type;
    if (accept)
      headers.Accept = accept;
    if (this.#token)
      headers.Authorization = `Bearer ${this.#token}`;
    const repeatable = method !== 'POST' || path.split('?')[0].endsWith('/query');
    for (let attempt = 0; ; attempt++) {
      let res;
      try {
        res = await this.#fetch(this.#base + path, { method, headers, body, signal });
      } catch (e) {
        if (attempt === 0 && repeatable && !signal?.aborted && e?.name === 'TypeError')
          continue;
        throw e;
      }
      if (!res.ok && !pass.includes(res.status))
        throw await errorFrom(res);
      return res;
    }
  }

  async #json(method, path, options) {
    return (await this.#request(method, path, options)).json();
  }

  /** GET /healthz: {status: "ok"} while the process runs. */
  health({ signal } = {}) {
    return this.#json('GET', '/healthz', { signal });
  }

  /** GET /readyz: {ready, status}; ready is false (status "loading" or "draining") on 503. */
  async ready({ signal } = {}) {
    const res = await this.#request('GET', '/readyz', { signal, pass: [503] });
    const body = await res.json();
    return { ready: res.status === 200, status: body.status };
  }

  /** GET /metrics: the Prometheus text. */
  async metrics({ signal } = {}) {
    return (await this.#request('GET', '/metrics', { signal })).text();
  }

  /* ---- meshes ---- */

  async meshes({ signal } = {}) {
    return (await this.#json('GET', '/v1/meshes', { signal })).meshes;
  }

  mesh(name, { signal } = {}) {
    return this.#json('GET', `/v1/meshes/${seg(name)}`, { signal });
  }

  /** PUT a mesh file (bytes, a Blob or its text); format "obj" | "ply" | "stl" | "off" or
   * sniffed by the server. Returns the report, with created: true when the name was new. */
  async putMesh(name, data, { format, signal } = {}) {
    const q = format ? `?format=${encodeURIComponent(format)}` : '';
    const res = await this.#request('PUT', `/v1/meshes/${seg(name)}${q}`,
      { body: data, type: 'application/octet-stream', signal });
    return { ...(await res.json()), created: res.status === 201 };
  }

  /** PUT /v1/meshes/{name} with the mesh as JSON arrays: `vertices` ([x, y, z] triples, or
   * flat numbers) and `faces` ([i, j, k] triples or flat indices from 0). */
  async putMeshArrays(name, { vertices, faces }, { signal } = {}) {
    const rows = (a, what) => {
      if (Array.isArray(a?.[0])) /* rows as given: the server names a ragged one */
        return a.map((r) => Array.from(r, Number));
      const flat = Array.from(a ?? []);
      if (flat.length % 3)
        throw new TypeError(`${what} must be triples, not ${flat.length} numbers`);
      const out = [];
      for (let i = 0; i < flat.length; i += 3)
        out.push([flat[i], flat[i + 1], flat[i + 2]].map(Number));
      return out;
    };
    const body = JSON.stringify({ vertices: rows(vertices, 'vertices'), faces: rows(faces, 'faces') });
    const res = await this.#request('PUT', `/v1/meshes/${seg(name)}?format=json`,
      { body, type: 'application/json', signal });
    return { ...(await res.json()), created: res.status === 201 };
  }

  async deleteMesh(name, { signal } = {}) {
    await this.#request('DELETE', `/v1/meshes/${seg(name)}`, { signal });
  }

  /** POST /v1/meshes/{name}/query: points (flat or triples) in the body form `form`
   * ("octet", "json" or "npy"), answered in form `accept` (default: the same). */
  async query(name, points, options = {}) {
    const { mode = 'signed', sign = 'auto', filter } = options;
    const w = WORDS[modeCode(mode)];
    signCode(sign);
    const f = checkFilter(filter);
    const hasFilter = Object.keys(f).length > 0;
    return this.#points(`/v1/meshes/${seg(name)}/query`, points, w, mode === 'closest', options,
      (body) => {
        body.mode = mode;
        body.sign = sign;
        if (hasFilter)
          body.filter = f;
      },
      (args) => {
        args.set('mode', mode);
        args.set('sign', sign);
        filterArgs(f, args);
      });
  }

  /** POST /v1/volumes/{name}/query: the baked volume's value (and gradient) at the points.
   * interpolation "default" (hermite on first-order volumes, trilinear on zero-order ones;
   * the server's default, so not sent), "trilinear", "nearest" or "hermite". */
  async queryVolume(name, points, options = {}) {
    const { interpolation = 'default', gradient = false } = options;
    const mode = gradient ? 'gradient' : 'value';
    const named = interpolation !== 'default';
    return this.#points(`/v1/volumes/${seg(name)}/query`, points, VOLUME_MODES[mode], false,
      options,
      (body) => {
        body.mode = mode;
        if (named)
          body.interpolation = interpolation;
      },
      (args) => {
        args.set('mode', mode);
        if (named)
          args.set('interpolation', interpolation);
      });
  }

  /* The query routes' shared body forms (docs/api.md, Request bodies and Responses): JSON
   * keys come from `jsonKeys`, URL arguments from `urlArgs`. */
  async #points(path, points, w, closest, options, jsonKeys, urlArgs) {
    const { form = 'octet', accept = form, signal } = options;
    const type = formType(form, 'form');
    const acceptType = formType(accept, 'accept');
    const p = toPoints(points);
    const count = p.length / 3;
    let body;
    if (form === 'json') {
      const keys = {};
      jsonKeys(keys);
      const extra = JSON.stringify(keys).slice(1, -1);
      body = `{"points":${jsonCoordinates(p)}${extra ? ',' + extra : ''}}`;
    } else {
      const args = new URLSearchParams();
      urlArgs(args);
      path += `?${args}`;
      body = form === 'npy' ? encodeNpy(p) : leBytes(p);
    }
    const res = await this.#request('POST', path, { body, type, accept: acceptType, signal });
    if (accept === 'json')
      return fromJson(await res.json(), count);
    const bytes = new Uint8Array(await res.arrayBuffer());
    const words = accept === 'npy' ? npyWords(bytes, count, w, closest) : leWords(bytes);
    return splitWords(words, count, w);
  }

  /* ---- slices ---- */

  /** GET /v1/meshes/{name}/slice.png, or with `volume: true` /v1/volumes/{name}/slice.png:
   * a plane of the field (docs/api.md, Slices). Options: axis, at, normal, origin (triples),
   * bounds ([x0, y0, z0, x1, y1, z1]), size, mode, sign, interpolation, step, filter (as in
   * query, for mode "filtered"), format ("png", default, or "npy"). Returns {format, bytes,
   * width, height, first, right, down, range, step} (pixel (i, j) is centred at first +
   * i right + j down), and for npy the values as a Float32Array of height x width. */
  async slice(name, options = {}) {
    const { volume = false, format = 'png', filter, signal, ...rest } = options;
    if (!['png', 'npy'].includes(format))
      throw new TypeError(`format must be "png" or "npy", not ${JSON.stringify(format)}`);
    const args = new URLSearchParams();
    for (const [k, v] of Object.entries(rest)) {
      if (v !== undefined)
        args.set(k, Array.isArray(v) || ArrayBuffer.isView(v) ? Array.from(v, String).join(',') : String(v));
    }
    if (filter)
      filterArgs(checkFilter(filter), args);
    if (format !== 'png')
      args.set('format', format);
    const query = args.toString() ? `?${args}` : '';
    const res = await this.#request('GET',
      `/v1/${volume ? 'volumes' : 'meshes'}/${seg(name)}/slice.png${query}`, { signal });
    const bytes = new Uint8Array(await res.arrayBuffer());
    const numbers = (h) => (res.headers.get(`X-SDF-Slice-${h}`) ?? '').split(',').map(Number);
    const [width, height] = numbers('Size');
    const out = {
      format, bytes, width, height, first: numbers('First'), right: numbers('Right'),
      down: numbers('Down'), range: numbers('Range'), step: numbers('Step')[0],
    };
    if (format === 'npy') {
      const a = parseNpy(bytes);
      if (a.descr !== '<f4' || a.shape.length !== 2 || a.shape[0] !== height || a.shape[1] !== width)
        throw new RangeError(`unexpected slice npy ${a.descr} ${a.shape}`);
      const w = leWords(a.data);
      out.values = new Float32Array(w.buffer, w.byteOffset, w.length);
    }
    return out;
  }

  /* ---- bakes and jobs ---- */

  /** POST /v1/meshes/{name}/bake with the parameters of docs/api.md's table (volume,
   * bounds, margin, resolution, order, H, delta, normalize, field, filter, encoding,
   * sign, and the field operations applied before the grid is stored: ops as volumeOps's,
   * solver, iterations, band, strict); the 202's job. Never re-sent on a dropped
   * connection: jobs() tells whether it started. */
  async bake(name, params = {}, { signal } = {}) {
    const body = params.ops === undefined ? params : { ...params, ops: toOps(params.ops) };
    return this.#json('POST', `/v1/meshes/${seg(name)}/bake`,
      { body: JSON.stringify(body), type: 'application/json', signal });
  }

  /** POST /v1/volumes/{name}/ops: field operations on a stored volume, in order, each
   * {round: 0.05} or ['round', 0.05] (redistance, offset, round, fillet, smooth); options
   * volume (the output's name), solver ("sussman", "sweep" or "exact"), iterations, band, strict.
   * The 202's job ("kind": "ops"; once done its caveats and warning), for waitJob. Never
   * re-sent on a dropped connection, as bake. */
  /** A volume's surface (GET /v1/volumes/{name}/mesh): with `mesh`, stored on the server
   * as that mesh (POST; its report, created: true when the name was new); with `format`
   * ("ply" | "obj" | "stl" | "off") the file {format, bytes, triangles}; else the arrays
   * {vertices: Float32Array (x, y, z each), triangles: Uint32Array (3 each)}. */
  async extractMesh(name, { iso = 0, cap = false, format, mesh, method = 'auto', signal } = {}) {
    if (mesh !== undefined) {
      const res = await this.#request('POST', `/v1/volumes/${seg(name)}/mesh`,
        { body: JSON.stringify({ mesh, iso, cap, method }), type: 'application/json', signal });
      return { ...(await res.json()), created: res.status === 201 };
    }
    if (!Number.isFinite(iso))
      throw new TypeError(`iso must be a finite number, not ${iso}`);
    const q = new URLSearchParams({ format: format ?? 'ply', iso: String(iso), cap: String(Boolean(cap)), method });
    const res = await this.#request('GET', `/v1/volumes/${seg(name)}/mesh?${q}`, { signal });
    const bytes = new Uint8Array(await res.arrayBuffer());
    const triangles = Number(res.headers.get('X-SDF-Triangles'));
    return format === undefined ? plyArrays(bytes) : { format, bytes, triangles };
  }

  async volumeOps(name, ops, { signal, ...params } = {}) {
    return this.#json('POST', `/v1/volumes/${seg(name)}/ops`,
      { body: JSON.stringify({ ...params, ops: toOps(ops) }), type: 'application/json', signal });
  }

  job(id, { signal } = {}) {
    return this.#json('GET', `/v1/jobs/${seg(id)}`, { signal });
  }

  async jobs({ signal } = {}) {
    return (await this.#json('GET', '/v1/jobs', { signal })).jobs;
  }

  /** DELETE /v1/jobs/{id}: cancel a queued or running job, or forget a finished one. */
  cancelJob(id, { signal } = {}) {
    return this.#json('DELETE', `/v1/jobs/${seg(id)}`, { signal });
  }

  /** Poll a job (its id or the job bake returned) until it ends: its final status when
   * done; an SdfError with the job's error when it failed (status 500) or was canceled
   * (409, ECANCELED); an Error named "TimeoutError" after `timeout` ms. */
  async waitJob(job, { timeout = 600000, interval = 50, signal, onProgress } = {}) {
    const id = typeof job === 'object' ? job.id : job;
    const deadline = Date.now() + timeout;
    for (;;) {
      const s = await this.job(id, { signal });
      onProgress?.(s);
      if (s.state === 'done')
        return s;
      if (s.state === 'failed' || s.state === 'canceled') {
        const e = s.error ?? { code: 'ECANCELED', message: 'the bake was canceled' };
        throw new SdfError(s.state === 'canceled' ? 409 : 500, e.code, e.message);
      }
      if (Date.now() > deadline) {
        const e = new Error(`job ${id} still ${s.state} after ${timeout} ms`);
        e.name = 'TimeoutError';
        throw e;
      }
      await sleep(interval, signal);
    }
  }

  /* ---- volumes ---- */

  async volumes({ signal } = {}) {
    return (await this.#json('GET', '/v1/volumes', { signal })).volumes;
  }

  volume(name, { signal } = {}) {
    return this.#json('GET', `/v1/volumes/${seg(name)}`, { signal });
  }

  /** PUT an EXR volume (a download in format "exr" from this or another server). Returns
   * the metadata, with created: true when the name was new. */
  async putVolume(name, exr, { signal } = {}) {
    const res = await this.#request('PUT', `/v1/volumes/${seg(name)}`,
      { body: exr, type: 'image/x-exr', signal });
    return { ...(await res.json()), created: res.status === 201 };
  }

  async deleteVolume(name, { signal } = {}) {
    await this.#request('DELETE', `/v1/volumes/${seg(name)}`, { signal });
  }

  /** GET /v1/volumes/{name}/data in format "exr" (default), "npy" or "raw": {bytes, dims,
   * order, encoding} from the headers, and for npy and raw the node words as `values`
   * (Float32Array, or Uint32Array for packed32) with their `shape`. */
  async download(name, { format = 'exr', signal } = {}) {
    if (!['exr', 'npy', 'raw'].includes(format))
      throw new TypeError(`format must be "exr", "npy" or "raw", not ${JSON.stringify(format)}`);
    const res = await this.#request('GET', `/v1/volumes/${seg(name)}/data?format=${format}`,
      { signal });
    const bytes = new Uint8Array(await res.arrayBuffer());
    const dims = (res.headers.get('X-SDF-Dims') ?? '').split(',').map(Number);
    const out = {
      format, bytes, dims, order: Number(res.headers.get('X-SDF-Order')),
      encoding: res.headers.get('X-SDF-Encoding'),
    };
    if (format === 'exr')
      return out;
    const packed = out.encoding === 'packed32';
    let data = bytes;
    let shape = [dims[2], dims[1], dims[0], ...(out.order === 1 && !packed ? [4] : [])];
    if (format === 'npy') {
      const a = parseNpy(bytes);
      if (a.descr !== (packed ? '<u4' : '<f4') || a.fortranOrder)
        throw new RangeError(`unexpected volume npy ${a.descr}`);
      data = a.data;
      shape = a.shape;
    }
    const words = leWords(data);
    out.shape = shape;
    out.values = packed ? words : new Float32Array(words.buffer, words.byteOffset, words.length);
    return out;
  }
}
