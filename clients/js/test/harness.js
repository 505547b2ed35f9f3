/* harness.js - the real sdfd for a test, on loopback ports the kernel picks (--http and
 * --bin on port 0; the ports are read from its JSON log's "listening" events, as
 * tests/server/harness.py does). Paths come from the environment meson sets: SDFD (the
 * daemon) and SDF_TEST_DATA (tests/data); run by hand, the defaults assume the repository's
 * build/ directory.
 *
 * Importing it checks every HTTP answer the test then receives against docs/openapi.yaml
 * (apicheck.js, as tests/server/harness.py does with apicheck.py): through fetch (Client
 * takes globalThis.fetch when it is made) and through node:https's request (Client's `ca`
 * option); an answer the document does not describe fails its fetch, and Server.stop() fails
 * as well. */
import { spawn } from 'node:child_process';
import { once } from 'node:events';
import { readFile } from 'node:fs/promises';
import https from 'node:https';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { checkedFetch, checkedRequest, violations } from './apicheck.js';

/* A module is evaluated once, so each is wrapped once however many tests import this. */
globalThis.fetch = checkedFetch(globalThis.fetch);
https.request = checkedRequest(https.request);

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..', '..');
export const SDFD = process.env.SDFD ?? path.join(root, 'build', 'server', 'sdfd');
export const DATA = process.env.SDF_TEST_DATA ?? path.join(root, 'tests', 'data');
export const PYTHON_CLIENT = path.join(root, 'clients', 'python');

export class Server {
  /** Start sdfd with `args` (each listener on `http` / `bin`, default port 0) and wait
   * until it is ready. */
  static async start(args = [], { http = 0, bin = 0 } = {}) {
    const s = new Server();
    s.seen = violations.length;
    s.proc = spawn(SDFD, ['--http', `127.0.0.1:${http}`, '--bin', `127.0.0.1:${bin}`, ...args],
      { stdio: ['ignore', 'ignore', 'pipe'] });
    s.logs = [];
    s.ports = {};
    s.exited = once(s.proc, 'exit');
    let rest = '';
    const ready = new Promise((resolve, reject) => {
      s.proc.stderr.on('data', (chunk) => {
        const lines = (rest + chunk).split('\n');
        rest = lines.pop();
        for (const line of lines) {
          let e;
          try {
            e = JSON.parse(line);
          } catch {
            e = { unparsed: line };
          }
          s.logs.push(e);
          if (e.event === 'listening')
            s.ports[e.proto] = e.port;
          if (e.event === 'ready')
            resolve();
        }
      });
      s.exited.then(([code]) => reject(new Error(`sdfd exited with ${code} before it was ready:\n`
        + s.logs.map((e) => JSON.stringify(e)).join('\n'))));
    });
    const timer = setTimeout(() => s.proc.kill('SIGKILL'), 60000);
    try {
      await ready;
    } finally {
      clearTimeout(timer);
    }
    return s;
  }

  get url() {
    return `http://127.0.0.1:${this.ports.http}`;
  }

  get binPort() {
    return this.ports.binary;
  }

  /** Signal it and wait for it to exit; returns its exit code. Throws, once it has exited,
   * when any answer since it started was outside docs/openapi.yaml: the test fails even if
   * the code under test caught the fetch's ApiViolation. */
  async stop(signal = 'SIGTERM') {
    if (this.proc.exitCode === null && this.proc.signalCode === null)
      this.proc.kill(signal);
    const [code] = await this.exited;
    const outside = violations.slice(this.seen);
    if (outside.length)
      throw new Error(`answers outside docs/openapi.yaml:\n${outside.join('\n')}`);
    return code;
  }
}

/** Are two typed arrays the same bytes? */
export function sameBits(a, b) {
  if (a.byteLength !== b.byteLength)
    return false;
  const x = new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
  const y = new Uint8Array(b.buffer, b.byteOffset, b.byteLength);
  return x.every((v, i) => v === y[i]);
}

/** N points uniform in [lo, hi]^3 from a seeded generator (mulberry32), as a Float32Array. */
export function randomPoints(n, seed, lo = -0.2, hi = 0.2) {
  let t = seed >>> 0;
  const next = () => {
    t = (t + 0x6d2b79f5) >>> 0;
    let r = Math.imul(t ^ (t >>> 15), 1 | t);
    r = (r + Math.imul(r ^ (r >>> 7), 61 | r)) ^ r;
    return ((r ^ (r >>> 14)) >>> 0) / 4294967296;
  };
  return Float32Array.from({ length: 3 * n }, () => lo + (hi - lo) * next());
}

/** Poll `predicate` (it may be async) every 20 ms until it holds or `ms` have passed; true if
 * it held. */
export async function waitUntil(predicate, ms = 10000) {
  const deadline = Date.now() + ms;
  for (;;) {
    if (await predicate())
      return true;
    if (Date.now() > deadline)
      return false;
    await new Promise((resolve) => setTimeout(resolve, 20));
  }
}

/** How many TCP connections the server side of 127.0.0.1:`port` holds established, from the
 * kernel's table (Linux's /proc/net/tcp): how a test sees that sdfd closed one. */
export async function establishedAt(port) {
  const local = `0100007F:${port.toString(16).toUpperCase().padStart(4, '0')}`;
  const rows = (await readFile('/proc/net/tcp', 'utf8')).split('\n').slice(1);
  return rows.filter((row) => {
    const f = row.trim().split(/\s+/);
    return f[1] === local && f[3] === '01';
  }).length;
}
