/* client-bench.js - the JS client's throughput on one request of every point, for
 * tests/bench/server-compare.sh, next to the in-process library on the same points. Not a
 * test: it asserts nothing but that the server answered.
 *
 *   node clients/js/bench/client-bench.js POINTS.npy --form binary|octet|json
 *        [--bin HOST:PORT] [--http URL] [--name NAME] [--repeat R] [--out OUT.f32]
 *
 * POINTS.npy is (N, 3) float32 (sdf-bench --points-out writes it). One query of all N points,
 * signed, sign auto, on mesh NAME (default demo): `binary` through BinaryClient (src/binary.js),
 * `octet` and `json` through Client (src/http.js, fetch) in that body form, the answer in the
 * same form. Sent once untimed, then R times (default 2), best reported. Timed is what a
 * program pays: from the Float32Array of points to the answer's Float32Array. --out writes
 * the distances as raw little-endian float32 (the data of sdf-bench --out's .npy), to be
 * compared byte for byte. Also printed: the client's CPU time (this process's, user and
 * system, every thread) per timed request, which the machine's other work inflates far less
 * than the wall time. The last line printed is `throughput: X Mq/s`. */
import { readFileSync, writeFileSync } from 'node:fs';
import { performance } from 'node:perf_hooks';
import { BinaryClient, Client, parseNpy } from 'sdfd-client';

function usage() {
  console.error('usage: node client-bench.js POINTS.npy --form binary|octet|json [--bin HOST:PORT]'
    + ' [--http URL] [--name NAME] [--repeat R] [--out OUT.f32]');
  process.exit(2);
}

function parseArgs(argv) {
  const a = { bin: '127.0.0.1:9090', http: 'http://127.0.0.1:8080', name: 'demo', repeat: 2 };
  for (let i = 0; i < argv.length; i++) {
    if (!argv[i].startsWith('--')) {
      if (a.points)
        usage();
      a.points = argv[i];
      continue;
    }
    const key = argv[i].slice(2), v = argv[++i];
    if (v === undefined || !['form', 'bin', 'http', 'name', 'repeat', 'out'].includes(key))
      usage();
    a[key] = key === 'repeat' ? Number(v) : v;
  }
  if (!a.points || !['binary', 'octet', 'json'].includes(a.form) || !(a.repeat >= 1))
    usage();
  return a;
}

function loadPoints(path) {
  const npy = parseNpy(readFileSync(path));
  if (npy.descr !== '<f4' || npy.fortranOrder || npy.shape.length !== 2 || npy.shape[1] !== 3)
    throw new Error(`${path}: expected a float32 (N, 3) array, not ${npy.descr} (${npy.shape})`);
  const points = new Float32Array(3 * npy.shape[0]); /* a copy: 4-aligned, of its own */
  new Uint8Array(points.buffer).set(npy.data.subarray(0, points.byteLength));
  return points;
}

const a = parseArgs(process.argv.slice(2));
const points = loadPoints(a.points);
const n = points.length / 3;
let query, close;
if (a.form === 'binary') {
  const colon = a.bin.lastIndexOf(':');
  const b = new BinaryClient({ host: a.bin.slice(0, colon), port: Number(a.bin.slice(colon + 1)) });
  query = () => b.query(a.name, points);
  close = () => b.close();
} else {
  const c = new Client(a.http);
  query = () => c.query(a.name, points, { form: a.form });
  close = () => {};
}
let best = Infinity, cpu = 0, answer;
for (let i = -1; i < a.repeat; i++) { /* i = -1: the untimed warm-up */
  const t0 = performance.now(), c0 = process.cpuUsage();
  answer = await query();
  const t = (performance.now() - t0) / 1e3, c = process.cpuUsage(c0);
  if (i >= 0) {
    best = Math.min(best, t);
    cpu += (c.user + c.system) / 1e3;
  }
}
await close();
if (answer.count !== n)
  throw new Error(`the answer holds ${answer.count} points, not ${n}`);
if (a.out)
  writeFileSync(a.out, new Uint8Array(answer.distance.buffer, answer.distance.byteOffset, 4 * n));
console.log(`points: ${n} client: sdfd-client.js form: ${a.form} requests: 1`);
console.log(`client cpu ms: ${(cpu / a.repeat).toFixed(1)}`);
console.log(`seconds: ${best.toFixed(4)}`);
console.log(`throughput: ${(n / best / 1e6).toFixed(4)} Mq/s`);
