/* loadworker.js - the JS client's share of deploy/failover.py's binary load: one BinaryClient
 * (resend on, the default) kept for the whole run, sending requests from a manifest one or
 * three at a time (pipelined) until a deadline, and comparing every answer's words bit for
 * bit with the reference's. Prints one JSON line of counts, which failover.py judges: this
 * program asserts nothing itself.
 *
 *   node clients/js/test/loadworker.js HOST PORT MANIFEST SECONDS SEED
 *
 * MANIFEST: one request a line, "KIND NAME MODE COUNT POINTS EXPECTED" (as
 * tests/clients/sdfc_load.c reads it): KIND `meshes` or `volumes`, POINTS a file of COUNT x 3
 * float32, EXPECTED one of the RESULT's words, little-endian. */
import { readFileSync } from 'node:fs';
import { BinaryClient } from 'sdfd-client';

const [host, port, manifest, seconds, seed] = process.argv.slice(2);
if (seed === undefined) {
  console.error('usage: node loadworker.js HOST PORT MANIFEST SECONDS SEED');
  process.exit(2);
}

const requests = readFileSync(manifest, 'utf8').split('\n').filter(Boolean).map((line) => {
  const [kind, name, mode, count, points, expected] = line.split(' ');
  const p = readFileSync(points);
  return {
    kind, name, mode, count: Number(count), expected: readFileSync(expected),
    points: new Float32Array(p.buffer, p.byteOffset, p.byteLength / 4),
  };
});

/* A result object's words in the wire's order: distance, then gradient or closest, then
 * the triangle. */
function words(r) {
  const parts = [r.distance, r.gradient ?? r.closest, r.triangle].filter(Boolean)
    .map((a) => new Uint32Array(a.buffer, a.byteOffset, a.length));
  const widths = parts.map((a) => a.length / r.count);
  const w = widths.reduce((x, y) => x + y, 0);
  const out = new Uint32Array(w * r.count);
  for (let i = 0; i < r.count; i++) {
    let at = i * w;
    parts.forEach((a, k) => {
      for (let j = 0; j < widths[k]; j++)
        out[at++] = a[i * widths[k] + j];
    });
  }
  return Buffer.from(out.buffer);
}

function ask(client, q) {
  return q.kind === 'volumes'
    ? client.queryVolume(q.name, q.points, { gradient: q.mode === 'gradient' })
    : client.query(q.name, q.points, { mode: q.mode });
}

let t = (Number(seed) * 2654435761) >>> 0;
function random() { /* mulberry32 */
  t = (t + 0x6d2b79f5) >>> 0;
  let r = Math.imul(t ^ (t >>> 15), 1 | t);
  r = (r + Math.imul(r ^ (r >>> 7), 61 | r)) ^ r;
  return ((r ^ (r >>> 14)) >>> 0) / 4294967296;
}

const tally = { sent: 0, ok: 0, failed: 0, mismatched: 0, connects: 0, resent: 0, errors: [], done_at: [] };
const client = new BinaryClient({ host, port: Number(port) });
const deadline = performance.now() + 1000 * Number(seconds);
while (performance.now() < deadline) {
  const k = random() < 0.25 ? 3 : 1;
  const batch = Array.from({ length: k }, () => requests[Math.floor(random() * requests.length)]);
  tally.sent += k;
  const got = await Promise.allSettled(batch.map((q) => ask(client, q)));
  got.forEach((r, i) => {
    const q = batch[i];
    if (r.status === 'rejected') {
      tally.failed++;
      if (tally.errors.length < 5)
        tally.errors.push(`${q.name} ${q.mode} (${q.count} points): ${r.reason?.code} ${r.reason?.message}`);
    } else if (!words(r.value).equals(q.expected)) {
      tally.mismatched++;
    } else {
      tally.ok++;
      tally.done_at.push(Date.now() / 1000);
    }
  });
}
tally.connects = client.stats.connects;
tally.resent = client.stats.resent;
await client.close();
console.log(JSON.stringify(tally));
