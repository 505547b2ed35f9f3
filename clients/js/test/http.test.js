/* http.test.js - Client against the real sdfd: every route of docs/api.md, the three body
 * forms giving the same bits (and the answer forms crossed), the filter parameters as JSON and
 * as URL arguments giving the same bits, volume downloads agreeing across formats and with
 * volume queries, the documented errors as SdfError, cancellation through AbortSignal, the
 * bearer token, and a request after the server closed an idle keep-alive connection. */
import assert from 'node:assert/strict';
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import { after, before, describe, test } from 'node:test';
import { Client, SdfError, parseNpy } from 'sdfd-client';
import { DATA, Server, establishedAt, randomPoints, sameBits, waitUntil } from './harness.js';

const FANDISK = path.join(DATA, 'fandisk.off');
const MODES = ['signed', 'distance', 'gradient', 'closest', 'filtered', 'filtered-gradient'];

function sameResult(a, b, what) {
  assert.equal(a.count, b.count, `${what}: count`);
  for (const k of ['distance', 'gradient', 'closest', 'triangle']) {
    assert.equal(a[k] === undefined, b[k] === undefined, `${what}: ${k} present in one only`);
    if (a[k] !== undefined)
      assert.ok(sameBits(a[k], b[k]), `${what}: ${k} differs`);
  }
}

async function rejectsWith(promise, status, code) {
  await assert.rejects(promise, (e) => {
    assert.ok(e instanceof SdfError, `not an SdfError: ${e}`);
    assert.equal(e.status, status, e.message);
    assert.equal(e.code, code, e.message);
    assert.ok(e.message.length > 0);
    return true;
  });
}

describe('HTTP client', { timeout: 120000 }, () => {
  let server, c;
  const points = randomPoints(500, 11);

  before(async () => {
    server = await Server.start(['--mesh', `fandisk=${FANDISK}`, '--max-bake-queries', '50000000']);
    c = new Client(server.url);
  });
  after(async () => {
    assert.equal(await server.stop(), 0);
  });

  test('healthz, readyz and metrics', async () => {
    assert.deepEqual(await c.health(), { status: 'ok' });
    assert.deepEqual(await c.ready(), { ready: true, status: 'ready' });
    const text = await c.metrics();
    const line = text.split('\n').find((l) => l.startsWith('sdfd_requests_total{route="/healthz",status="200"}'));
    assert.ok(line && Number(line.split(' ').pop()) >= 1, 'the healthz request is counted');
    assert.match(text, /^sdfd_meshes_loaded 1$/m);
  });

  test('mesh list, report, put (new and replaced) and delete', async () => {
    const list = await c.meshes();
    assert.deepEqual(list.map((m) => m.name), ['fandisk']);
    const report = await c.mesh('fandisk');
    assert.equal(report.triangles, list[0].triangles);
    assert.equal(report.closed, true);
    const cube = await readFile(path.join(DATA, 'cube.ply'));
    const put = await c.putMesh('cube', cube);
    assert.equal(put.created, true);
    assert.equal(put.name, 'cube');
    assert.equal(put.format, 'ply');
    assert.equal(put.triangles, 12);
    const obj = 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n';
    const replaced = await c.putMesh('cube', obj, { format: 'obj' });
    assert.equal(replaced.created, false);
    assert.equal(replaced.triangles, 4);
    assert.deepEqual((await c.meshes()).map((m) => m.name), ['cube', 'fandisk']);
    /* a point inside the tetrahedron, 0.1 from its three axis faces */
    const r = await c.query('cube', [0.1, 0.1, 0.1]);
    assert.equal(r.distance[0], Math.fround(-0.1));
    /* the same tetrahedron as arrays: the same answer, bit for bit */
    const arrays = await c.putMeshArrays('tetra', {
      vertices: new Float32Array([0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1]),
      faces: [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    });
    assert.equal(arrays.created, true);
    assert.equal(arrays.triangles, 4);
    assert.equal(arrays.closed, true);
    assert.equal((await c.query('tetra', [0.1, 0.1, 0.1])).distance[0], r.distance[0]);
    await rejectsWith(c.putMeshArrays('bad', { vertices: [[0, 0, 0]], faces: [[0, 1, 2]] }), 422, 'EINVAL');
    await assert.rejects(c.putMeshArrays('bad', { vertices: [0, 0], faces: [] }), TypeError);
    await c.deleteMesh('tetra');
    await c.deleteMesh('cube');
    await rejectsWith(c.mesh('cube'), 404, 'ENOTFOUND');
    await rejectsWith(c.putMesh('bad', 'v 0 0 zero\nf 1 2 3\n', { format: 'obj' }), 422, 'EPARSE');
  });

  test('every mode answers the same bits in every body and answer form', async () => {
    for (const mode of MODES) {
      const filter = mode.startsWith('filtered') ? { samples: 8 } : undefined;
      const base = await c.query('fandisk', points, { mode, filter });
      assert.equal(base.count, 500);
      assert.equal(base.gradient !== undefined, mode.endsWith('gradient'));
      assert.equal(base.triangle !== undefined, mode === 'closest');
      for (const form of ['octet', 'json', 'npy']) {
        for (const accept of ['octet', 'json', 'npy'])
          sameResult(await c.query('fandisk', points, { mode, filter, form, accept }), base, `${mode} ${form}->${accept}`);
      }
    }
  });

  test('points as triples, flat numbers, Float64Array and Float32Array agree', async () => {
    const p = randomPoints(20, 3);
    const triples = Array.from({ length: 20 }, (_, i) => Array.from(p.subarray(3 * i, 3 * i + 3)));
    const base = await c.query('fandisk', p, { mode: 'gradient' });
    for (const input of [triples, Array.from(p), Float64Array.from(p)])
      sameResult(await c.query('fandisk', input, { mode: 'gradient' }), base, 'input form');
    await assert.rejects(c.query('fandisk', [1, 2]), TypeError);
    await assert.rejects(c.query('fandisk', [[1, 2]]), TypeError);
    await assert.rejects(c.query('fandisk', p, { mode: 'nearest' }), TypeError);
  });

  test('a -0 coordinate reaches the server as -0 in every form', async () => {
    const p = new Float32Array([-0, 0.05, -0]);
    const base = await c.query('fandisk', p, { mode: 'closest' });
    sameResult(await c.query('fandisk', p, { mode: 'closest', form: 'json' }), base, '-0 json');
  });

  test('filter parameters as JSON and as URL arguments give the same bits', async () => {
    const filters = [
      { samples: 16, seed: 7, grid: true, kernel: 'gaussian' },
      { samples: 12, min_samples: 4, unsigned: true, cap: 0.05 },
      { samples: 8, smooth: { sphere: [0, 0, 0, 0.1], depth: 0.02, scale: 0.5 } },
      { samples: 8, smooth: { box: [-0.1, -0.1, -0.1, 0.1, 0.1, 0.1] } },
      { samples: 8, smooth: { mesh: 'fandisk' } },
    ];
    for (const filter of filters) {
      const json = await c.query('fandisk', points, { mode: 'filtered-gradient', filter, form: 'json' });
      const octet = await c.query('fandisk', points, { mode: 'filtered-gradient', filter });
      sameResult(octet, json, JSON.stringify(filter));
      const plain = await c.query('fandisk', points, { mode: 'filtered-gradient', filter: { samples: 8 } });
      if (filter.samples === 8)
        assert.ok(!sameBits(octet.distance, plain.distance), `${JSON.stringify(filter)} changes nothing`);
    }
    await assert.rejects(c.query('fandisk', points, { mode: 'filtered', filter: { sample: 8 } }), TypeError);
  });

  test('a bigint seed is the same seed in every form; one past 2^53 is refused', async () => {
    const want = await c.query('fandisk', points, { mode: 'filtered', filter: { samples: 8, seed: 7 } });
    for (const form of ['json', 'octet', 'npy'])
      sameResult(await c.query('fandisk', points, { mode: 'filtered', form, filter: { samples: 8, seed: 7n } }),
        want, `seed 7n, ${form}`);
    await assert.rejects(c.query('fandisk', points, { mode: 'filtered', form: 'json',
      filter: { samples: 8, seed: 2n ** 53n + 1n } }), RangeError);
  });

  test('slices: PNG and npy, the plane in the headers, the values those of a query', async () => {
    const png = await c.slice('fandisk', { axis: 'y', at: 0.01, size: 64 });
    assert.equal(png.format, 'png');
    assert.deepEqual([...png.bytes.subarray(0, 8)], [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]);
    assert.equal(Math.max(png.width, png.height), 64);
    const npy = await c.slice('fandisk', { axis: 'y', at: 0.01, size: 64, format: 'npy' });
    assert.equal(npy.values.length, npy.width * npy.height);
    assert.deepEqual([npy.width, npy.height, npy.first, npy.right, npy.down],
      [png.width, png.height, png.first, png.right, png.down]);
    /* the centre of pixel (i, j) queried on its own gives that pixel's value */
    for (const [i, j] of [[0, 0], [7, 30], [npy.width - 1, npy.height - 1]]) {
      const p = [0, 1, 2].map((a) => npy.first[a] + i * npy.right[a] + j * npy.down[a]);
      assert.ok(Math.abs(p[1] - 0.01) < 1e-6);
      const q = await c.query('fandisk', [p]);
      assert.ok(Math.abs(q.distance[0] - npy.values[j * npy.width + i]) < 1e-6, `pixel ${i}, ${j}`);
    }
    const lo = Math.min(...npy.values), hi = Math.max(...npy.values);
    assert.ok(Math.abs(npy.range[0] - lo) < 1e-6 && Math.abs(npy.range[1] - hi) < 1e-6);
    const filtered = await c.slice('fandisk', { size: 32, format: 'npy', mode: 'filtered', filter: { samples: 8, seed: 2 } });
    const raw = await c.slice('fandisk', { size: 32, format: 'npy' });
    assert.ok(!sameBits(filtered.values, raw.values), 'the filter arguments changed nothing');
    const plane = await c.slice('fandisk', { normal: [0, 0, 1], origin: [0, 0, 0.1], bounds: [-1, -1, -1, 1, 1, 1], size: 16, format: 'npy' });
    assert.deepEqual([plane.width, plane.height], [16, 16]);
    await assert.rejects(c.slice('fandisk', { format: 'gif' }), TypeError);
    await rejectsWith(c.slice('fandisk', { size: 0 }), 422, 'EINVAL');
    await rejectsWith(c.slice('fandisk', { volume: true }), 404, 'ENOTFOUND');
  });

  test('errors: unknown mesh 404, bad bodies and values 422', async () => {
    await rejectsWith(c.query('nope', points), 404, 'ENOTFOUND');
    await rejectsWith(c.query('nope', points, { form: 'json' }), 404, 'ENOTFOUND');
    await rejectsWith(c.mesh('nope'), 404, 'ENOTFOUND');
    await rejectsWith(c.query('fandisk', [0, Number.NaN, 0]), 422, 'ENONFINITE');
    await rejectsWith(c.query('fandisk', [0, 0, 0], { form: 'npy', mode: 'filtered', filter: { samples: 0 } }), 422, 'EINVAL');
    await rejectsWith(c.query('fandisk', [0, 0, 0], { mode: 'filtered', filter: { cap: -1 } }), 422, 'EINVAL');
    await rejectsWith(c.bake('fandisk', { resolution: 1 }), 422, 'EINVAL');
    await rejectsWith(c.job('no-such-job'), 404, 'ENOTFOUND');
    await assert.rejects(c.query('fandisk', [0, Number.POSITIVE_INFINITY, 0], { form: 'json' }), RangeError);
  });

  test('bake, poll, download in every format, volume queries, put and delete', async () => {
    const job = await c.bake('fandisk', { volume: 'v1', resolution: [12, 10, 8], order: 1 });
    assert.ok(['queued', 'running', 'done'].includes(job.state));
    const seen = [];
    const done = await c.waitJob(job, { onProgress: (s) => seen.push(s.state) });
    assert.equal(done.state, 'done');
    assert.equal(done.progress, 1);
    assert.equal(seen.at(-1), 'done');
    assert.ok((await c.jobs()).some((j) => j.id === job.id));
    assert.equal((await c.job(job.id)).volume, 'v1');

    const meta = await c.volume('v1');
    assert.deepEqual(meta.dims, [12, 10, 8]);
    assert.deepEqual((await c.volumes()).map((v) => v.name), ['v1']);
    const npy = await c.download('v1', { format: 'npy' });
    const raw = await c.download('v1', { format: 'raw' });
    const exr = await c.download('v1');
    assert.deepEqual(npy.dims, [12, 10, 8]);
    assert.equal(npy.order, 1);
    assert.equal(npy.encoding, 'float32');
    assert.deepEqual(npy.shape, [8, 10, 12, 4]);
    assert.equal(npy.values.length, 8 * 10 * 12 * 4);
    assert.ok(sameBits(npy.values, raw.values), 'npy and raw hold the same node words');
    assert.deepEqual(parseNpy(npy.bytes).shape, [8, 10, 12, 4]);
    assert.equal(exr.format, 'exr');
    assert.deepEqual(Array.from(exr.bytes.subarray(0, 4)), [0x76, 0x2f, 0x31, 0x01]); /* EXR magic */

    const p = randomPoints(300, 5, -0.6, 0.6);
    const answers = {};
    for (const interpolation of ['default', 'trilinear', 'nearest', 'hermite']) {
      for (const gradient of [false, true]) {
        const base = await c.queryVolume('v1', p, { interpolation, gradient });
        assert.equal(base.gradient !== undefined, gradient);
        for (const form of ['json', 'npy'])
          sameResult(await c.queryVolume('v1', p, { interpolation, gradient, form }), base, `volume ${interpolation} ${form}`);
        answers[`${interpolation} ${gradient}`] = base;
      }
    }
    /* no interpolation is the default, hermite on this first-order volume */
    sameResult(await c.queryVolume('v1', p, { gradient: true }), answers['hermite true'], 'the default');
    assert.ok(!sameBits(answers['hermite true'].distance, answers['trilinear true'].distance),
      'hermite and trilinear differ');
    /* a zero-order volume: at node (3, 2, 1) the nearest lookup is that node's word */
    await c.waitJob(await c.bake('fandisk', { volume: 'v0', resolution: [12, 10, 8] }));
    const zero = await c.download('v0', { format: 'npy' });
    assert.deepEqual(zero.shape, [8, 10, 12]);
    assert.ok(sameBits(zero.values, (await c.download('v0', { format: 'raw' })).values));
    const m0 = await c.volume('v0');
    const node = [0, 1, 2].map((a) => m0.origin[a] + [3, 2, 1][a] * m0.spacing[a]);
    const at = await c.queryVolume('v0', node, { interpolation: 'nearest' });
    assert.equal(at.distance[0], zero.values[(1 * 10 + 2) * 12 + 3]);
    await rejectsWith(c.queryVolume('v0', node, { interpolation: 'hermite' }), 422, 'EINVAL');
    await c.deleteVolume('v0');

    const copy = await c.putVolume('v2', exr.bytes);
    assert.equal(copy.created, true);
    assert.deepEqual(copy.dims, [12, 10, 8]);
    sameResult(await c.queryVolume('v2', p, { gradient: true }), await c.queryVolume('v1', p, { gradient: true }), 'copied volume');
    assert.equal((await c.putVolume('v2', exr.bytes)).created, false);
    await rejectsWith(c.putVolume('v3', npy.bytes), 415, 'EFORMAT');
    await c.deleteVolume('v2');
    await rejectsWith(c.volume('v2'), 404, 'ENOTFOUND');
    await rejectsWith(c.queryVolume('v2', p), 404, 'ENOTFOUND');
    await rejectsWith(c.download('v2', { format: 'raw' }), 404, 'ENOTFOUND');
    await c.deleteVolume('v1');
  });

  test('extractMesh: the surface as arrays, as a file, and stored as a mesh', async () => {
    await c.waitJob(await c.bake('fandisk', { volume: 'surf', resolution: 24 }));
    const { vertices, triangles } = await c.extractMesh('surf');
    assert.ok(triangles.length > 300 && triangles.length % 3 === 0, `${triangles.length}`);
    assert.equal(Math.max(...triangles) + 1, vertices.length / 3);
    const stl = await c.extractMesh('surf', { format: 'stl' });
    assert.equal(stl.triangles, triangles.length / 3);
    assert.equal(stl.bytes.length, 84 + 50 * stl.triangles);
    const stored = await c.extractMesh('surf', { mesh: 'surf-mesh', cap: true });
    assert.deepEqual([stored.created, stored.closed, stored.triangles], [true, true, stl.triangles]);
    await rejectsWith(c.extractMesh('surf', { format: '3ds' }), 422, 'EINVAL');
    await assert.rejects(c.extractMesh('surf', { iso: NaN }), TypeError);
    await c.deleteMesh('surf-mesh');
    await c.deleteVolume('surf');
  });

  test('field operations: volumeOps and a bake with ops end done on the source grid', async () => {
    await c.waitJob(await c.bake('fandisk', { volume: 'src', resolution: [20, 18, 16] }));
    const job = await c.volumeOps('src', [{ round: 0.05 }, ['fillet', 0.03]],
      { volume: 'rounded', solver: 'sussman', iterations: 5 });
    assert.deepEqual([job.kind, job.source, job.volume], ['ops', 'src', 'rounded']);
    assert.ok(['queued', 'running', 'done'].includes(job.state), job.state);
    const done = await c.waitJob(job);
    assert.equal(done.state, 'done');
    assert.ok(Array.isArray(done.caveats), 'caveats is a list');
    assert.deepEqual((await c.volume('rounded')).dims, (await c.volume('src')).dims);
    const baked = await c.waitJob(await c.bake('fandisk',
      { volume: 'baked-ops', resolution: [20, 18, 16], ops: [['offset', -0.02]], solver: 'sweep' }));
    assert.equal(baked.state, 'done');
    assert.ok(Array.isArray(baked.caveats), 'a bake with ops lists caveats');
    assert.deepEqual((await c.volume('baked-ops')).dims, [20, 18, 16]);
    await rejectsWith(c.volumeOps('src', [{ sharpen: 0.1 }]), 422, 'EINVAL');
    await rejectsWith(c.volumeOps('nope', [{ round: 0.05 }]), 404, 'ENOTFOUND');
    await assert.rejects(c.volumeOps('src', [['round']]), TypeError);
    await assert.rejects(c.volumeOps('src', { round: 0.05 }), TypeError);
    for (const v of ['src', 'rounded', 'baked-ops'])
      await c.deleteVolume(v);
  });

  test('a canceled bake ends the wait with ECANCELED; a finished job can be forgotten', async () => {
    const job = await c.bake('fandisk', { volume: 'big', resolution: 96, order: 1 });
    const status = await c.cancelJob(job.id);
    assert.equal(status.id, job.id);
    await assert.rejects(c.waitJob(job), (e) => e instanceof SdfError && e.status === 409);
    assert.equal((await c.job(job.id)).state, 'canceled');
    await c.cancelJob(job.id);
    await rejectsWith(c.job(job.id), 404, 'ENOTFOUND');
    await rejectsWith(c.volume('big'), 404, 'ENOTFOUND');
  });

  test('waitJob gives up after its timeout', async () => {
    const job = await c.bake('fandisk', { volume: 'slow', resolution: 96, order: 1 });
    await assert.rejects(c.waitJob(job, { timeout: 30 }), (e) => e.name === 'TimeoutError');
    await c.cancelJob(job.id);
    await assert.rejects(c.waitJob(job), SdfError);
  });

  test('AbortSignal cancels a request before and while it runs', async () => {
    const early = new AbortController();
    early.abort();
    await assert.rejects(c.query('fandisk', points, { signal: early.signal }), { name: 'AbortError' });
    /* a filtered query of 4000 points x 1024 samples takes the server a second or more */
    const late = new AbortController();
    const big = randomPoints(4000, 9);
    const started = Date.now();
    const pending = c.query('fandisk', big, { mode: 'filtered', filter: { samples: 1024 }, signal: late.signal });
    setTimeout(() => late.abort(), 50);
    await assert.rejects(pending, { name: 'AbortError' });
    assert.ok(Date.now() - started < 2000, 'the abort did not wait for the answer');
    const job = await c.bake('fandisk', { volume: 'w', resolution: 96, order: 1 });
    const waiting = new AbortController();
    setTimeout(() => waiting.abort(), 50);
    await assert.rejects(c.waitJob(job, { signal: waiting.signal }), { name: 'AbortError' });
    await c.cancelJob(job.id);
    await assert.rejects(c.waitJob(job), SdfError);
    /* the client goes on working */
    assert.equal((await c.query('fandisk', points)).count, 500);
  });

  test('a request the connection dropped is sent again, a bake is not', async () => {
    let calls = 0;
    const flaky = (url, init) => {
      calls++;
      if (calls === 1)
        return Promise.reject(new TypeError('fetch failed'));
      return fetch(url, init);
    };
    const f = new Client(server.url, { fetch: flaky });
    assert.equal((await f.query('fandisk', points)).count, 500);
    assert.equal(calls, 2);
    calls = 0;
    await assert.rejects(f.bake('fandisk', { volume: 'x', resolution: 4 }), TypeError);
    assert.equal(calls, 1);
  });
});

describe('HTTP client against a server with --token and a 2 s idle timeout', { timeout: 60000 }, () => {
  let server;
  before(async () => {
    server = await Server.start(['--mesh', `fandisk=${FANDISK}`, '--token', 'sesame', '--auth-queries', '--timeout', '2']);
  });
  after(async () => {
    assert.equal(await server.stop(), 0);
  });

  test('the bearer token', async () => {
    const anon = new Client(server.url);
    const auth = new Client(server.url, { token: 'sesame' });
    const wrong = new Client(server.url, { token: 'open' });
    assert.deepEqual((await anon.meshes()).map((m) => m.name), ['fandisk']);
    await rejectsWith(anon.query('fandisk', [0, 0, 0]), 401, 'EUNAUTHORIZED');
    await rejectsWith(wrong.query('fandisk', [0, 0, 0]), 401, 'EUNAUTHORIZED');
    await rejectsWith(anon.deleteMesh('fandisk'), 401, 'EUNAUTHORIZED');
    assert.equal((await auth.query('fandisk', [0, 0, 0])).count, 1);
  });

  test('a request after the server closed the idle connection', async () => {
    const auth = new Client(server.url, { token: 'sesame' });
    const first = await auth.query('fandisk', randomPoints(10, 1));
    const port = server.ports.http;
    assert.ok(await establishedAt(port) >= 1, 'the kept-alive connection is open');
    assert.ok(await waitUntil(async () => await establishedAt(port) === 0, 10000),
      'sdfd did not close the idle connection (--timeout 2)');
    const again = await auth.query('fandisk', randomPoints(10, 1));
    sameResult(again, first, 'after the idle close');
  });
});
