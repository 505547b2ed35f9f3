// types.ts - compiled (never run) by types.test.js with tsc --noEmit: the hand-written .d.ts
// files must describe the API the way the README uses it, through the package's own
// "exports" (the node entry by name, the browser entry by its subpath).
import { BinaryClient, Client, SdfError, parseNpy, type QueryResult } from 'sdfd-client';
import * as browser from 'sdfd-client/browser';

async function http(): Promise<number> {
  const c = new Client('http://127.0.0.1:8080', { token: 't' });
  const r: QueryResult = await c.query('demo', [[0, 0, 0]], { mode: 'gradient', form: 'npy', signal: new AbortController().signal });
  const g: Float32Array | undefined = r.gradient;
  const job = await c.bake('demo', { volume: 'v', resolution: [8, 8, 8], order: 1 });
  const done = await c.waitJob(job, { onProgress: (j) => j.progress });
  const d = await c.download(done.volume, { format: 'npy' });
  const v = await c.queryVolume('v', new Float32Array(3), { gradient: true, accept: 'json', interpolation: 'hermite' });
  const ops = await c.volumeOps('v', [{ round: 0.05 }, ['fillet', 0.02]], { volume: 'w', solver: 'sweep', strict: true });
  const caveats: unknown[] | undefined = (await c.waitJob(ops)).caveats;
  await c.bake('demo', { volume: 'r', ops: [['offset', -0.1]], iterations: 10 });
  // @ts-expect-error an operation the API does not have
  await c.volumeOps('v', [{ sharpen: 1 }]);
  // @ts-expect-error an interpolation the API does not have
  await c.queryVolume('v', [0, 0, 0], { interpolation: 'cubic' });
  const created: boolean = (await c.putMesh('m', 'v 0 0 0\n', { format: 'obj' })).created;
  await c.deleteVolume('v');
  const f = await c.query('demo', [0, 0, 0], { mode: 'filtered', filter: { samples: 8, smooth: { sphere: [0, 0, 0, 1], depth: 0.1 } } });
  return r.count + (g?.length ?? 0) + (d.values?.length ?? 0) + v.distance.length + f.count + (created ? 1 : 0) + parseNpy(d.bytes).shape.length + (caveats?.length ?? 0);
}

async function binary(): Promise<number> {
  const b = new BinaryClient({ port: 9090, token: 't', maxInFlight: 8 });
  const h = await b.hello();
  const r = await b.query('demo', new Float32Array(6), { mode: 'closest', signal: new AbortController().signal });
  const t: Uint32Array | undefined = r.triangle;
  await b.close();
  return h.maxPoints + (t?.[0] ?? 0) + b.stats.resent;
}

function errors(e: unknown): string {
  return e instanceof SdfError ? `${e.status} ${e.code} ${e.message}` : String(e);
}

// The browser entry has no BinaryClient.
// @ts-expect-error
browser.BinaryClient;
const c2: browser.Client = new browser.Client();

export { http, binary, errors, c2 };

async function tls(): Promise<number> {
  const c = new Client('https://127.0.0.1:8080', { ca: '-----BEGIN CERTIFICATE-----\n' });
  const b = new BinaryClient({ port: 9090, tls: true, ca: new Uint8Array(1) });
  const h = await b.hello();
  return (await c.health()).status.length + h.version;
}

export { tls };
