/* wire.js - the bytes both of sdfd's protocols share: points (flat or triples) as
 * little-endian float32, answers as W 32-bit words per point split into Float32Arrays, the
 * names of modes, signs and message types, and the .npy framing the HTTP API also speaks.
 * Kept apart from the transports so the browser entry and the node-only binary client
 * decode one way. */

export const MODES = Object.freeze({
  signed: 0, distance: 1, gradient: 2, closest: 3, filtered: 4, 'filtered-gradient': 5,
});
export const SIGNS = Object.freeze({ auto: 0, pseudonormal: 1, winding: 2, raycast: 3, none: 4 });
/** Words per point of each mode's answer (docs/api.md, proto/PROTOCOL.md). */
export const WORDS = Object.freeze([1, 1, 4, 5, 1, 4]);
/** The binary protocol's message types (proto/PROTOCOL.md). */
export const FRAMES = Object.freeze({
  HELLO: 0x01, LIST_MESHES: 0x02, QUERY: 0x03, VOLUME_QUERY: 0x04, AUTH: 0x05, ERROR: 0x7f,
  HELLO_OK: 0x81, MESHES: 0x82, RESULT: 0x83, AUTH_OK: 0x85,
});
/** A volume query's interpolations and their VOLUME_QUERY codes (proto/PROTOCOL.md);
 * "default" is hermite on first-order volumes and trilinear on zero-order ones. */
export const INTERPOLATIONS = Object.freeze({ trilinear: 0, nearest: 1, hermite: 2, default: 3 });

/* Typed arrays use the host's byte order; the wire is little-endian. Big-endian hosts are
 * rare but the swap costs nothing where it is not needed. */
const LITTLE = new Uint8Array(new Uint32Array([1]).buffer)[0] === 1;

export function modeCode(mode) {
  const m = MODES[mode];
  if (m === undefined || !Object.hasOwn(MODES, mode))
    throw new TypeError(`unknown mode ${JSON.stringify(mode)} (known: ${Object.keys(MODES).join(', ')})`);
  return m;
}

export function signCode(sign) {
  const s = SIGNS[sign];
  if (s === undefined || !Object.hasOwn(SIGNS, sign))
    throw new TypeError(`unknown sign ${JSON.stringify(sign)} (known: ${Object.keys(SIGNS).join(', ')})`);
  return s;
}

/** Points as a Float32Array of 3N coordinates: a Float32Array is used as it is; other
 * typed arrays and flat number arrays are converted; an array of [x, y, z] triples is
 * flattened. */
export function toPoints(points) {
  let out;
  if (points instanceof Float32Array) {
    out = points;
  } else if (ArrayBuffer.isView(points) && !(points instanceof DataView)) {
    out = Float32Array.from(points);
  } else if (Array.isArray(points)) {
    if (points.length > 0 && typeof points[0] !== 'number') {
      out = new Float32Array(points.length * 3);
      for (let i = 0; i < points.length; i++) {
        const p = points[i];
        if (p == null || p.length !== 3)
          throw new TypeError(`points[${i}] is not an [x, y, z] triple`);
        out[3 * i] = p[0];
        out[3 * i + 1] = p[1];
        out[3 * i + 2] = p[2];
      }
      return out;
    }
    out = Float32Array.from(points);
  } else {
    throw new TypeError('points must be a Float32Array, an array of numbers or of [x, y, z] triples');
  }
  if (out.length % 3 !== 0)
    throw new TypeError(`a flat points array needs 3 numbers a point; got ${out.length}`);
  return out;
}

function swap32(bytes) {
  const out = new Uint8Array(bytes.length);
  for (let i = 0; i + 3 < bytes.length; i += 4) {
    out[i] = bytes[i + 3];
    out[i + 1] = bytes[i + 2];
    out[i + 2] = bytes[i + 1];
    out[i + 3] = bytes[i];
  }
  return out;
}

/** The little-endian bytes of a 32-bit typed array (a view of it on little-endian hosts). */
export function leBytes(array) {
  const bytes = new Uint8Array(array.buffer, array.byteOffset, array.byteLength);
  return LITTLE ? bytes : swap32(bytes);
}

/** 32-bit words from little-endian bytes, as a Uint32Array (copied only when the bytes are
 * not 4-aligned or the host is big-endian). */
export function leWords(bytes) {
  if (bytes.byteLength % 4 !== 0)
    throw new RangeError(`${bytes.byteLength} bytes are not a whole number of 32-bit words`);
  if (!LITTLE)
    bytes = swap32(bytes);
  else if (bytes.byteOffset % 4 !== 0)
    bytes = bytes.slice();
  return new Uint32Array(bytes.buffer, bytes.byteOffset, bytes.byteLength / 4);
}

/** Split N points' answer words (W words each, wire layout) into the result object:
 * distance always; gradient (W 4) or closest and triangle (W 5), each flat. The floats are
 * copied as words, so every bit (a -0, a NaN's payload) arrives as the server sent it. */
export function splitWords(words, count, w) {
  if (words.length !== count * w)
    throw new RangeError(`expected ${count} x ${w} answer words, got ${words.length}`);
  const distance = new Float32Array(count);
  if (w === 1) {
    new Uint32Array(distance.buffer).set(words);
    return { count, distance };
  }
  const d = new Uint32Array(distance.buffer);
  const vec = new Float32Array(3 * count);
  const v = new Uint32Array(vec.buffer);
  for (let i = 0, j = 0; i < count; i++, j += w) {
    d[i] = words[j];
    v[3 * i] = words[j + 1];
    v[3 * i + 1] = words[j + 2];
    v[3 * i + 2] = words[j + 3];
  }
  if (w === 4)
    return { count, distance, gradient: vec };
  const triangle = new Uint32Array(count);
  for (let i = 0; i < count; i++)
    triangle[i] = words[i * w + 4];
  return { count, distance, closest: vec, triangle };
}

/* ---- .npy (NumPy's format, versions 1-3) -------------------------------------------------- */

const NPY_MAGIC = [0x93, 0x4e, 0x55, 0x4d, 0x50, 0x59]; /* \x93NUMPY */

/** A version-1 .npy file of shape (N, 3) float32 holding the points (3N floats). */
export function encodeNpy(points) {
  const n = points.length / 3;
  let header = `{'descr': '<f4', 'fortran_order': False, 'shape': (${n}, 3), }`;
  /* NumPy aligns the data to 64 bytes: magic (6) + version (2) + length (2) + header + \n */
  const total = Math.ceil((10 + header.length + 1) / 64) * 64;
  header = header.padEnd(total - 10 - 1, ' ') + '\n';
  const out = new Uint8Array(total + points.byteLength);
  out.set(NPY_MAGIC, 0);
  out[6] = 1;
  out[7] = 0;
  out[8] = header.length & 0xff;
  out[9] = header.length >> 8;
  for (let i = 0; i < header.length; i++)
    out[10 + i] = header.charCodeAt(i);
  out.set(leBytes(points), total);
  return out;
}

/** Parse a .npy file's header: { descr, fortranOrder, shape, data } where data is a view of
 * the bytes after the header (checked to hold at least the shape's items for the simple
 * 4-byte dtypes). Throws a RangeError on anything that is not a .npy file. */
export function parseNpy(bytes) {
  if (!(bytes instanceof Uint8Array))
    bytes = new Uint8Array(bytes);
  if (bytes.length < 10 || NPY_MAGIC.some((b, i) => bytes[i] !== b))
    throw new RangeError('not a .npy file (no \\x93NUMPY magic)');
  const major = bytes[6];
  if (major < 1 || major > 3)
    throw new RangeError(`unsupported .npy version ${major}`);
  const wide = major >= 2;
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (wide && bytes.length < 12)
    throw new RangeError('truncated .npy header');
  const hlen = wide ? view.getUint32(8, true) : view.getUint16(8, true);
  const start = wide ? 12 : 10;
  if (start + hlen > bytes.length)
    throw new RangeError('truncated .npy header');
  const text = new TextDecoder().decode(bytes.subarray(start, start + hlen));
  const descr = /'descr':\s*(?:'([^']*)'|(\[.*\]))\s*,/.exec(text);
  const fortran = /'fortran_order':\s*(True|False)/.exec(text);
  const shape = /'shape':\s*\(([^)]*)\)/.exec(text);
  if (!descr || !fortran || !shape)
    throw new RangeError(`unreadable .npy header ${JSON.stringify(text.trim())}`);
  const dims = shape[1].split(',').map((s) => s.trim()).filter((s) => s).map(Number);
  if (dims.some((d) => !Number.isSafeInteger(d) || d < 0))
    throw new RangeError(`bad .npy shape (${shape[1]})`);
  const data = bytes.subarray(start + hlen);
  const type = descr[1] ?? descr[2].replace(/\s+/g, '');
  const items = dims.reduce((a, b) => a * b, 1);
  if ((type === '<f4' || type === '<u4') && data.length < 4 * items)
    throw new RangeError(`.npy data holds ${data.length} bytes, its shape needs ${4 * items}`);
  return { descr: type, fortranOrder: fortran[1] === 'True', shape: dims, data };
}

/** The descr NumPy writes for the closest mode's structured answer. */
export const CLOSEST_DESCR = "[('distance','<f4'),('closest','<f4',(3,)),('triangle','<u4')]";

/* ---- the filtered modes' parameters (docs/filtered.md) ------------------------------------ */

export const FILTER_KEYS = Object.freeze(['kernel', 'cap', 'a', 'b', 'samples', 'min_samples',
  'medial', 'grid', 'unsigned', 'allow_wide_bump', 'sample_gradient', 'seed', 'smooth']);
const SMOOTH_KINDS = ['sphere', 'box', 'mesh'];

/** The filter parameters as given, after refusing keys the server does not know (a typo
 * would otherwise reach it only as a URL argument's 422, or not at all on the binary
 * protocol's fixed block). */
export function checkFilter(filter) {
  const f = filter ?? {};
  if (typeof f !== 'object' || Array.isArray(f))
    throw new TypeError('filter must be an object of filter parameters');
  const unknown = Object.keys(f).filter((k) => !FILTER_KEYS.includes(k));
  if (unknown.length)
    throw new TypeError(`unknown filter parameters ${unknown.join(', ')} (known: ${FILTER_KEYS.join(', ')})`);
  if (typeof f.seed !== 'bigint')
    return f;
  /* JSON has no bigint (JSON.stringify throws on one): every seed the server takes, 0..2^53,
   * is exact as a number. */
  if (f.seed < 0n || f.seed > 2n ** 53n)
    throw new RangeError(`filter.seed must be an integer 0..2^53, not ${f.seed}`);
  return { ...f, seed: Number(f.seed) };
}

/** The one volume of a "smooth" object: [kind, value]. */
export function smoothVolume(smooth) {
  const kinds = SMOOTH_KINDS.filter((k) => k in smooth);
  if (kinds.length !== 1)
    throw new TypeError('filter.smooth needs exactly one of "sphere", "box" or "mesh"');
  return [kinds[0], smooth[kinds[0]]];
}

/** Field operations as the API's JSON list [{round: 0.05}, ...] (docs/api.md), from objects
 * of one key or [name, r] pairs; the server checks the names and numbers. */
export function toOps(ops) {
  if (!Array.isArray(ops))
    throw new TypeError('ops must be an array of operations, e.g. [{ round: 0.05 }]');
  return ops.map((op, i) => {
    if (Array.isArray(op) && op.length === 2 && typeof op[0] === 'string')
      return { [op[0]]: op[1] };
    if (op !== null && typeof op === 'object' && !Array.isArray(op) && Object.keys(op).length === 1)
      return { ...op };
    throw new TypeError(`ops[${i}] is neither {name: r} nor [name, r]: ${JSON.stringify(op)}`);
  });
}
