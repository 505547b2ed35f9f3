/* exact.test.js - the JavaScript client's answers against the Python client's
 * (clients/python/sdfclient/, run by python3 as a subprocess on the same points file, the
 * same server): every query mode and a volume query, through each of the JavaScript
 * client's ways (HTTP octet, JSON and npy bodies, the binary protocol), must give the same
 * float32 bits as Python's HTTP npy answer and its binary-protocol answer. The Python client
 * is tested against the library itself (tests/server/test_api.py), so this ties the
 * JavaScript client to the library's bits too. PYTHON names the interpreter (meson passes
 * the one with numpy it found). */
import assert from 'node:assert/strict';
import { execFile } from 'node:child_process';
import { existsSync } from 'node:fs';
import { mkdtemp, readFile, rm, writeFile } from 'node:fs/promises';
import os from 'node:os';
import path from 'node:path';
import { promisify } from 'node:util';
import { after, before, test } from 'node:test';
import { BinaryClient, Client } from 'sdfd-client';
import { DATA, PYTHON_CLIENT, Server, randomPoints } from './harness.js';

/* as tests/meson.build: Debian's python3, whose numpy the server tests use, before PATH's */
const PYTHON = process.env.PYTHON ?? (existsSync('/usr/bin/python3') ? '/usr/bin/python3' : 'python3');
const MODES = ['signed', 'distance', 'gradient', 'closest', 'filtered', 'filtered-gradient'];
const FILTER = { samples: 16, seed: 3 };

/* Writes, for each mode and way ("http", "binary"), the answer's arrays one after another
 * (distance, then gradient or closest and triangle) as little-endian bytes. */
const SCRIPT = `
import sys, numpy as np
sys.path.insert(0, sys.argv[1])
import sdfclient
url, port, points, out = sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5]
p = np.fromfile(points, dtype="<f4").reshape(-1, 3)
http = sdfclient.Client(url)
binary = sdfclient.BinaryClient("127.0.0.1", port)
filter = ${JSON.stringify(FILTER)}
def save(name, r):
    with open(f"{out}/{name}", "wb") as f:
        for k in ("distance", "gradient", "closest", "triangle"):
            if k in r:
                f.write(np.ascontiguousarray(r[k]).astype(r[k].dtype.newbyteorder("<")).tobytes())
for mode in ${JSON.stringify(MODES)}:
    f = filter if mode.startswith("filtered") else None
    save(mode + ".http", http.query("fandisk", p, mode=mode, filter=f))
    save(mode + ".binary", binary.query("fandisk", p, mode=mode, filter=f))
save("volume.http", http.query_volume("vol", p, gradient=True))
save("volume.binary", binary.query_volume("vol", p, gradient=True))
`;

function bytesOf(r) {
  const parts = ['distance', 'gradient', 'closest', 'triangle'].filter((k) => r[k])
    .map((k) => Buffer.from(r[k].buffer, r[k].byteOffset, r[k].byteLength));
  return Buffer.concat(parts);
}

let server, dir, http, binary;
const points = randomPoints(2000, 42, -0.3, 0.3);

before(async () => {
  server = await Server.start(['--mesh', `fandisk=${path.join(DATA, 'fandisk.off')}`]);
  http = new Client(server.url);
  binary = new BinaryClient({ port: server.binPort });
  await http.waitJob(await http.bake('fandisk', { volume: 'vol', resolution: 16, order: 1 }));
  dir = await mkdtemp(path.join(os.tmpdir(), 'sdfd-js-'));
  await writeFile(path.join(dir, 'points.f32'), points);
  await promisify(execFile)(PYTHON, ['-c', SCRIPT, PYTHON_CLIENT, server.url,
    String(server.binPort), path.join(dir, 'points.f32'), dir]);
});

after(async () => {
  await binary.close();
  await rm(dir, { recursive: true, force: true });
  assert.equal(await server.stop(), 0);
});

for (const mode of MODES) {
  test(`${mode}: every way gives the Python client's bits`, async () => {
    const py = await readFile(path.join(dir, `${mode}.http`));
    assert.ok(py.equals(await readFile(path.join(dir, `${mode}.binary`))), 'Python http vs binary');
    const filter = mode.startsWith('filtered') ? FILTER : undefined;
    const words = { signed: 1, distance: 1, gradient: 4, closest: 5 }[mode] ?? (mode === 'filtered' ? 1 : 4);
    assert.equal(py.length, 4 * words * 2000);
    for (const form of ['octet', 'json', 'npy'])
      assert.ok(py.equals(bytesOf(await http.query('fandisk', points, { mode, form, filter }))), `http ${form}`);
    assert.ok(py.equals(bytesOf(await binary.query('fandisk', points, { mode, filter }))), 'binary');
  });
}

test('volume query: every way gives the Python client\'s bits', async () => {
  const py = await readFile(path.join(dir, 'volume.http'));
  assert.ok(py.equals(await readFile(path.join(dir, 'volume.binary'))));
  assert.equal(py.length, 4 * 4 * 2000);
  for (const form of ['octet', 'json', 'npy'])
    assert.ok(py.equals(bytesOf(await http.queryVolume('vol', points, { gradient: true, form }))), `http ${form}`);
  assert.ok(py.equals(bytesOf(await binary.queryVolume('vol', points, { gradient: true }))), 'binary');
});
