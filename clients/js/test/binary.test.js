/* binary.test.js - BinaryClient against the real sdfd: HELLO, LIST_MESHES, QUERY in every
 * mode and VOLUME_QUERY answering the same bits as the HTTP API's octet-stream answers (the
 * FILTER block against the same parameters as URL arguments), errors as SdfError with the
 * connection kept, many requests pipelined on one connection under a full socket buffer,
 * AbortSignal, reconnecting after the server went away, the one re-send of requests a dying
 * connection took with it (through a loopback proxy that cuts the connection on cue), and
 * AUTH with --token. */
import assert from 'node:assert/strict';
import net from 'node:net';
import path from 'node:path';
import { after, before, describe, test } from 'node:test';
import { setTimeout as sleep } from 'node:timers/promises';
import { BinaryClient, Client, SdfError } from 'sdfd-client';
import { DATA, Server, randomPoints, sameBits } from './harness.js';

const FANDISK = path.join(DATA, 'fandisk.off');

function sameResult(a, b, what) {
  assert.equal(a.count, b.count, `${what}: count`);
  for (const k of ['distance', 'gradient', 'closest', 'triangle']) {
    assert.equal(a[k] === undefined, b[k] === undefined, `${what}: ${k} present in one only`);
    if (a[k] !== undefined)
      assert.ok(sameBits(a[k], b[k]), `${what}: ${k} differs`);
  }
}

function isSdfError(status, code) {
  return (e) => e instanceof SdfError && e.status === status && e.code === code && e.message.length > 0;
}

/* A loopback proxy to `port`. Connection i follows plan[i] (the last entry for the rest):
 * "pass" relays both ways; "cut" relays the handshake (client bytes up to `handshake`) and
 * its replies, then swallows replies and closes both ends once the client has sent `cutAt`
 * bytes, so that every request it carried dies in flight; "hold" stops reading from the
 * client after the handshake until resume(), so that the client's writes fill the socket. */
async function proxy(port, plan, handshake, cutAt) {
  let n = 0;
  const sockets = new Set();
  const held = [];
  const server = net.createServer((client) => {
    const mode = plan[Math.min(n++, plan.length - 1)];
    const upstream = net.connect({ host: '127.0.0.1', port });
    sockets.add(client).add(upstream);
    let sent = 0;
    client.on('data', (d) => {
      sent += d.length;
      upstream.write(d);
      if (mode === 'cut' && sent >= cutAt) {
        client.destroy();
        upstream.destroy();
      }
      if (mode === 'hold' && sent > handshake && !held.includes(client)) {
        client.pause();
        held.push(client);
      }
    });
    upstream.on('data', (d) => {
      if (mode !== 'cut' || sent <= handshake)
        client.write(d);
    });
    for (const s of [client, upstream]) {
      s.on('error', () => {});
      s.on('close', () => {
        client.destroy();
        upstream.destroy();
      });
    }
  });
  await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
  return {
    port: server.address().port,
    get connections() {
      return n;
    },
    resume: () => held.forEach((s) => s.resume()),
    close: () => {
      for (const s of sockets)
        s.destroy();
      return new Promise((resolve) => server.close(resolve));
    },
  };
}

describe('binary client', { timeout: 120000 }, () => {
  let server, http, b;
  const points = randomPoints(400, 21);

  before(async () => {
    server = await Server.start(['--mesh', `fandisk=${FANDISK}`, '--max-points', '100000']);
    http = new Client(server.url);
    b = new BinaryClient({ port: server.binPort });
  });
  after(async () => {
    await b.close();
    assert.equal(await server.stop(), 0);
  });

  test('HELLO and LIST_MESHES', async () => {
    const h = await b.hello();
    assert.equal(h.version, 1);
    assert.equal(h.maxPoints, 100000);
    assert.equal(h.maxPayload, 12 * 100000 + 4096);
    assert.match(h.server, /^sdfd /);
    assert.deepEqual(await b.meshes(), await http.meshes());
  });

  test('QUERY in every mode answers the HTTP octet answer bit for bit', async () => {
    for (const mode of ['signed', 'distance', 'gradient', 'closest']) {
      for (const sign of mode === 'signed' ? ['auto', 'winding', 'raycast'] : ['auto'])
        sameResult(await b.query('fandisk', points, { mode, sign }), await http.query('fandisk', points, { mode, sign }), `${mode} ${sign}`);
    }
  });

  test('the FILTER block carries what the URL arguments carry', async () => {
    const filters = [
      { samples: 16, seed: 7 },
      { samples: 12, min_samples: 4, unsigned: true, cap: 0.05, a: 0.5 },
      { samples: 8, grid: true },
      { samples: 8, sample_gradient: true, medial: 0.3 },
      { kernel: 'bump', samples: 8, b: 0.01 },
      { samples: 8, smooth: { sphere: [0, 0, 0, 0.1], depth: 0.02, scale: 0.5 } },
      { samples: 8, smooth: { box: [-0.1, -0.1, -0.1, 0.1, 0.1, 0.1] } },
      { samples: 8, smooth: { mesh: 'fandisk' } },
    ];
    const seen = new Set();
    for (const filter of filters) {
      for (const mode of ['filtered', 'filtered-gradient']) {
        const got = await b.query('fandisk', points, { mode, filter });
        sameResult(got, await http.query('fandisk', points, { mode, filter }), `${mode} ${JSON.stringify(filter)}`);
        seen.add(Buffer.from(got.distance.buffer).toString('base64'));
      }
    }
    assert.ok(seen.size >= filters.length, 'the parameters change the answers');
    await assert.rejects(b.query('fandisk', points, { mode: 'filtered', filter: { samples: 5000 } }), isSdfError(422, 'EINVAL'));
    await assert.rejects(b.query('fandisk', points, { mode: 'filtered', filter: { smooth: { mesh: 'nope' } } }), isSdfError(404, 'ENOTFOUND'));
    await assert.rejects(b.query('fandisk', points, { mode: 'filtered', filter: { kernel: 'box' } }), TypeError);
  });

  test('VOLUME_QUERY answers what the HTTP volume query answers', async () => {
    await http.waitJob(await http.bake('fandisk', { volume: 'vol', resolution: 10, order: 1 }));
    const p = randomPoints(300, 2, -0.6, 0.6);
    for (const interpolation of ['default', 'trilinear', 'nearest', 'hermite']) {
      for (const gradient of [false, true]) {
        sameResult(await b.queryVolume('vol', p, { interpolation, gradient }),
          await http.queryVolume('vol', p, { interpolation, gradient }), `volume ${interpolation} ${gradient}`);
      }
    }
    /* the default is hermite on this first-order volume, over both protocols */
    sameResult(await b.queryVolume('vol', p), await b.queryVolume('vol', p, { interpolation: 'hermite' }), 'binary default');
    sameResult(await http.queryVolume('vol', p), await b.queryVolume('vol', p), 'the defaults');
    /* and trilinear on a zero-order one, where hermite is the same refusal as over HTTP */
    await http.waitJob(await http.bake('fandisk', { volume: 'vol0', resolution: 10 }));
    sameResult(await b.queryVolume('vol0', p), await http.queryVolume('vol0', p, { interpolation: 'trilinear' }), 'zero-order default');
    const refusal = (e) => [e.status, e.code, e.message];
    const overHttp = await http.queryVolume('vol0', p, { interpolation: 'hermite' }).catch(refusal);
    const overBinary = await b.queryVolume('vol0', p, { interpolation: 'hermite' }).catch(refusal);
    assert.deepEqual(overBinary, overHttp);
    assert.equal(overBinary[0], 422);
    await assert.rejects(b.queryVolume('none', p), isSdfError(404, 'ENOTFOUND'));
    await assert.rejects(b.queryVolume('vol', p, { interpolation: 'cubic' }), TypeError);
  });

  test('errors leave the connection open', async () => {
    const before = b.stats.connects;
    await assert.rejects(b.query('nope', points), isSdfError(404, 'ENOTFOUND'));
    await assert.rejects(b.query('fandisk', [0, Number.NaN, 0]), isSdfError(422, 'ENONFINITE'));
    /* over max_payload: refused here, where the server would close the connection */
    await assert.rejects(b.query('fandisk', new Float32Array(3 * 100400)), RangeError);
    await assert.rejects(b.query('', points), RangeError);
    assert.equal((await b.query('fandisk', points)).count, 400);
    assert.equal(b.stats.connects, before);
  });

  test('hundreds of pipelined requests, answers matched by request id', async () => {
    const c = new BinaryClient({ port: server.binPort });
    const all = randomPoints(300 * 50, 8);
    const ref = await http.query('fandisk', all, { mode: 'gradient' });
    const answers = await Promise.all(Array.from({ length: 300 }, (_, i) =>
      c.query('fandisk', all.subarray(150 * i, 150 * (i + 1)), { mode: 'gradient' })));
    answers.forEach((r, i) => {
      assert.ok(sameBits(r.distance, ref.distance.subarray(50 * i, 50 * (i + 1))), `request ${i}`);
      assert.ok(sameBits(r.gradient, ref.gradient.subarray(150 * i, 150 * (i + 1))), `request ${i}`);
    });
    assert.equal(c.stats.maxInFlight, 64, 'the window filled');
    assert.equal(c.stats.connects, 1);
    await c.close();
  });

  test('writes wait for drain while the peer does not read, and arrive whole', async () => {
    /* 18 MB of requests against a proxy that stops reading: more than loopback's socket
     * buffers hold, so socket.write must report a full buffer before the proxy resumes */
    const px = await proxy(server.binPort, ['hold'], 16 + 'sdfd-client.js'.length);
    const c = new BinaryClient({ port: px.port, maxInFlight: 1000 });
    try {
      const all = randomPoints(30 * 50000, 4);
      const part = (i) => all.subarray(150000 * i, 150000 * (i + 1));
      await c.hello();
      const pending = Promise.all(Array.from({ length: 30 }, (_, i) => c.query('fandisk', part(i))));
      for (let t = 0; t < 3000 && c.stats.backpressure === 0; t++) /* up to 30 s on a busy machine */
        await sleep(10);
      assert.ok(c.stats.backpressure > 0, 'socket.write reported a full buffer');
      px.resume();
      const answers = await pending;
      for (let i = 0; i < 30; i++)
        assert.ok(sameBits(answers[i].distance, (await http.query('fandisk', part(i))).distance), `request ${i}`);
      /* Pipelined past the full buffer. Not necessarily all 30 at once: once the proxy
       * resumes, the first answers can arrive while the last requests are still waiting for
       * drain. */
      assert.ok(c.stats.maxInFlight > 1 && c.stats.maxInFlight <= 30, `${c.stats.maxInFlight} in flight`);
      assert.equal(c.stats.connects, 1);
    } finally {
      await c.close();
      await px.close();
    }
  });

  test('AbortSignal: a queued request never leaves, an answered-late one is skipped', async () => {
    const c = new BinaryClient({ port: server.binPort, maxInFlight: 1 });
    const early = new AbortController();
    early.abort();
    await assert.rejects(c.query('fandisk', points, { signal: early.signal }), { name: 'AbortError' });
    const slow = c.query('fandisk', randomPoints(2000, 1), { mode: 'filtered', filter: { samples: 512 } });
    const queued = new AbortController();
    const waiting = c.query('fandisk', points, { signal: queued.signal });
    queued.abort();
    await assert.rejects(waiting, { name: 'AbortError' });
    assert.equal((await slow).count, 2000);
    const inflight = new AbortController();
    const gone = c.query('fandisk', randomPoints(2000, 2), { mode: 'filtered', filter: { samples: 512 }, signal: inflight.signal });
    setTimeout(() => inflight.abort(), 20);
    await assert.rejects(gone, { name: 'AbortError' });
    /* the next answer on the connection is this request's, not the abandoned one's */
    sameResult(await c.query('fandisk', points), await http.query('fandisk', points), 'after an abort');
    assert.equal(c.stats.connects, 1);
    await c.close();
  });

  test('requests on a connection that dies are re-sent once on a new one', async () => {
    const handshake = 16 + 'sdfd-client.js'.length;
    const frame = 16 + 8 + 8 + 12 * 100; /* "fandisk" pads to 8 */
    const p = randomPoints(100 * 5, 6);
    const ref = await http.query('fandisk', p);
    const ask = (c) => Promise.all(Array.from({ length: 5 }, (_, i) =>
      c.query('fandisk', p.subarray(300 * i, 300 * (i + 1)))));

    let px = await proxy(server.binPort, ['cut', 'pass'], handshake, handshake + 5 * frame);
    let c = new BinaryClient({ port: px.port });
    const answers = await ask(c);
    answers.forEach((r, i) => assert.ok(sameBits(r.distance, ref.distance.subarray(100 * i, 100 * (i + 1)))));
    assert.deepEqual([c.stats.connects, c.stats.resent, px.connections], [2, 5, 2]);
    await c.close();
    await px.close();

    /* once only: a second death fails them */
    px = await proxy(server.binPort, ['cut'], handshake, handshake + 5 * frame);
    c = new BinaryClient({ port: px.port });
    await assert.rejects(ask(c), { code: 'ECONNRESET' });
    assert.deepEqual([c.stats.connects, c.stats.resent], [2, 5]);
    await c.close();
    await px.close();

    /* and never with resend: false */
    px = await proxy(server.binPort, ['cut', 'pass'], handshake, handshake + 5 * frame);
    c = new BinaryClient({ port: px.port, resend: false });
    await assert.rejects(ask(c), { code: 'ECONNRESET' });
    assert.equal(c.stats.resent, 0);
    /* the connection after is a new one, and works */
    sameResult(await c.query('fandisk', p), ref, 'after the cut');
    assert.equal(c.stats.connects, 2);
    await c.close();
    await px.close();
  });
});

describe('binary client across a server restart and with --token', { timeout: 60000 }, () => {
  test('an idle connection the server closed is replaced on the next request', async () => {
    let server = await Server.start(['--mesh', `fandisk=${FANDISK}`]);
    const port = server.binPort;
    const c = new BinaryClient({ port });
    const p = randomPoints(50, 3);
    const first = await c.query('fandisk', p, { mode: 'closest' });
    assert.equal(await server.stop(), 0);
    /* nothing listens now: the request fails, it does not hang */
    await assert.rejects(c.query('fandisk', p), { code: 'ECONNREFUSED' });
    server = await Server.start(['--mesh', `fandisk=${FANDISK}`], { bin: port });
    try {
      sameResult(await c.query('fandisk', p, { mode: 'closest' }), first, 'after the restart');
      assert.equal(c.stats.connects, 2);
      assert.equal(c.stats.resent, 0);
    } finally {
      await c.close();
      assert.equal(await server.stop(), 0);
    }
  });

  test('AUTH', async () => {
    const server = await Server.start(['--mesh', `fandisk=${FANDISK}`, '--token', 'sesame', '--auth-queries']);
    try {
      const anon = new BinaryClient({ port: server.binPort });
      assert.equal((await anon.hello()).version, 1);
      assert.equal((await anon.meshes()).length, 1, 'LIST_MESHES needs no token');
      await assert.rejects(anon.query('fandisk', [0, 0, 0]), isSdfError(401, 'EUNAUTHORIZED'));
      await anon.auth('sesame');
      assert.equal((await anon.query('fandisk', [0, 0, 0])).count, 1);
      await anon.close();

      const auth = new BinaryClient({ port: server.binPort, token: 'sesame' });
      assert.equal((await auth.query('fandisk', [0, 0, 0])).count, 1);
      await auth.close();

      const wrong = new BinaryClient({ port: server.binPort, token: 'open' });
      await assert.rejects(wrong.query('fandisk', [0, 0, 0]), isSdfError(401, 'EUNAUTHORIZED'));
      await wrong.close();

      const late = new BinaryClient({ port: server.binPort });
      await assert.rejects(late.auth('guess'), isSdfError(401, 'EUNAUTHORIZED'));
      await late.close();
    } finally {
      assert.equal(await server.stop(), 0);
    }
  });
});
