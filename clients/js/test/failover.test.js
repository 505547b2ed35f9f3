/* failover.test.js - BinaryClient behind a load balancer whose replicas go away, against the
 * real sdfd through a loopback proxy that stands for the balancer: a query a draining
 * replica refuses (503 EUNAVAILABLE) is sent once more on a new connection and answers the
 * bits a direct query answers; refused again, or with resend: false, it is the caller's
 * SdfError. A connection reset as soon as it is accepted is replaced before its handshake
 * (three attempts in all, then the reset is the caller's error). */
import assert from 'node:assert/strict';
import net from 'node:net';
import path from 'node:path';
import { after, before, describe, test } from 'node:test';
import { BinaryClient, SdfError } from 'sdfd-client';
import { DATA, Server, randomPoints, sameBits } from './harness.js';

const FANDISK = path.join(DATA, 'fandisk.off');
const QUERY = 0x03, VOLUME_QUERY = 0x04, ERROR = 0x7f;

/* Splits one direction's byte stream into frames (a 16-byte header whose last word is the
 * payload's length): onHeader(header) says whether to drop the frame, emit(bytes) gets the
 * kept bytes in order, onEnd() runs after each frame. idle(): between two frames. */
function framer(onHeader, emit, onEnd) {
  const hdr = Buffer.alloc(16);
  let got = 0, left = 0, drop = false;
  return {
    idle: () => got === 0,
    push(chunk) {
      for (let at = 0; at < chunk.length;) {
        if (got < 16) {
          const take = Math.min(16 - got, chunk.length - at);
          chunk.copy(hdr, got, at, at + take);
          got += take;
          at += take;
          if (got < 16)
            continue;
          left = hdr.readUInt32LE(12);
          drop = onHeader(hdr);
          if (!drop)
            emit(Buffer.from(hdr));
        } else {
          const take = Math.min(left, chunk.length - at);
          if (!drop)
            emit(chunk.subarray(at, at + take));
          left -= take;
          at += take;
        }
        if (got === 16 && left === 0) {
          got = 0;
          onEnd();
        }
      }
    },
  };
}

/* The ERROR frame a draining sdfd answers a query with (proto/PROTOCOL.md, ERROR). */
function unavailable(rid) {
  const code = Buffer.from('EUNAVAILABLE'), message = Buffer.from('the server is shutting down');
  const payload = Buffer.alloc(6 + code.length + message.length);
  payload.writeUInt16LE(503, 0);
  payload.writeUInt16LE(code.length, 2);
  code.copy(payload, 4);
  payload.writeUInt16LE(message.length, 4 + code.length);
  message.copy(payload, 6 + code.length);
  const head = Buffer.from([0x53, 0x44, 0x46, 0x50, 1, ERROR, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
  head.writeUInt32LE(rid, 8);
  head.writeUInt32LE(payload.length, 12);
  return Buffer.concat([head, payload]);
}

/* A loopback proxy to `port`. Connection i follows plan[i] (the last entry for the rest):
 * "pass" relays both ways; "reset" resets the connection as soon as it is accepted;
 * "refuse" relays all but the first QUERY or VOLUME_QUERY, which it answers itself with the
 * draining server's ERROR, put between two of the server's reply frames. */
async function proxy(port, plan) {
  let n = 0;
  const sockets = new Set();
  const server = net.createServer((client) => {
    const mode = plan[Math.min(n++, plan.length - 1)];
    client.on('error', () => {});
    if (mode === 'reset') {
      client.resetAndDestroy();
      return;
    }
    const upstream = net.connect({ host: '127.0.0.1', port });
    sockets.add(client).add(upstream);
    let refused = mode !== 'refuse', error = null;
    const flush = () => {
      if (error && down.idle()) {
        client.write(error);
        error = null;
      }
    };
    const up = framer((h) => {
      if (refused || (h[5] !== QUERY && h[5] !== VOLUME_QUERY))
        return false;
      refused = true;
      error = unavailable(h.readUInt32LE(8));
      return true;
    }, (b) => upstream.write(b), () => {});
    const down = framer(() => false, (b) => client.write(b), flush);
    client.on('data', (d) => {
      up.push(d);
      flush();
    });
    upstream.on('data', (d) => down.push(d));
    upstream.on('error', () => {});
    for (const s of [client, upstream]) {
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
    close: () => {
      for (const s of sockets)
        s.destroy();
      return new Promise((resolve) => server.close(resolve));
    },
  };
}

describe('binary client behind a balancer whose replicas go away', { timeout: 120000 }, () => {
  let server, direct;
  const p = randomPoints(100 * 5, 8);
  const parts = Array.from({ length: 5 }, (_, i) => p.subarray(300 * i, 300 * (i + 1)));
  const ask = (c) => Promise.allSettled(parts.map((q) => c.query('fandisk', q, { mode: 'gradient' })));
  let ref;

  before(async () => {
    server = await Server.start(['--mesh', `fandisk=${FANDISK}`]);
    direct = new BinaryClient({ port: server.binPort });
    ref = await Promise.all(parts.map((q) => direct.query('fandisk', q, { mode: 'gradient' })));
  });
  after(async () => {
    await direct.close();
    assert.equal(await server.stop(), 0);
  });

  /* Every answer that came is the direct one's bits; how many came. */
  function answered(got, what) {
    const ok = got.filter((r) => r.status === 'fulfilled');
    got.forEach((r, i) => {
      for (const k of ['distance', 'gradient'])
        assert.ok(r.status !== 'fulfilled' || sameBits(r.value[k], ref[i][k]),
          `${what}: query ${i}: ${k} differs`);
    });
    return ok.length;
  }

  function sameAnswers(got, what) {
    assert.equal(answered(got, what), got.length,
      `${what}: ${got.map((r) => r.reason).filter(Boolean).join('; ')}`);
  }

  test('a query refused as unavailable goes once more on a new connection', async () => {
    const px = await proxy(server.binPort, ['refuse', 'pass']);
    const c = new BinaryClient({ port: px.port });
    try {
      sameAnswers(await ask(c), 'refused first');
      /* the other four were answered on the first connection: only the refused one went again */
      assert.deepEqual([c.stats.connects, c.stats.resent, px.connections], [2, 1, 2]);
    } finally {
      await c.close();
      await px.close();
    }
  });

  test('refused twice, or without resend, the refusal is the caller\'s', async () => {
    for (const [plan, resend, connects] of [[['refuse'], true, 2], [['refuse', 'pass'], false, 1]]) {
      const px = await proxy(server.binPort, plan);
      const c = new BinaryClient({ port: px.port, resend });
      try {
        const got = await ask(c);
        const refused = got.filter((r) => r.status === 'rejected');
        assert.equal(refused.length, 1, `resend ${resend}`);
        assert.ok(refused[0].reason instanceof SdfError && refused[0].reason.status === 503
          && refused[0].reason.code === 'EUNAVAILABLE', String(refused[0].reason));
        assert.equal(answered(got, `resend ${resend}`), 4);
        assert.deepEqual([c.stats.connects, c.stats.resent, px.connections],
          [connects, connects - 1, connects]);
      } finally {
        await c.close();
        await px.close();
      }
    }
  });

  test('a connection reset as soon as it is accepted is replaced', async () => {
    const px = await proxy(server.binPort, ['reset', 'reset', 'pass']);
    const c = new BinaryClient({ port: px.port });
    try {
      sameAnswers(await ask(c), 'after two resets');
      assert.equal(px.connections, 3);
      /* a connection reset before node saw it connect never counts */
      assert.ok(c.stats.connects >= 1 && c.stats.connects <= 3, `${c.stats.connects}`);
      assert.equal(c.stats.resent, 0);
    } finally {
      await c.close();
      await px.close();
    }
  });

  test('three handshakes reset in a row are the caller\'s error', async () => {
    const px = await proxy(server.binPort, ['reset']);
    const c = new BinaryClient({ port: px.port });
    try {
      const got = await ask(c);
      assert.ok(got.every((r) => r.status === 'rejected' && r.reason.code === 'ECONNRESET'),
        got.map((r) => r.reason?.code).join(' '));
      assert.equal(px.connections, 3);
      /* and the next request starts afresh, three more attempts */
      await assert.rejects(c.query('fandisk', parts[0]), { code: 'ECONNRESET' });
      assert.equal(px.connections, 6);
    } finally {
      await c.close();
      await px.close();
    }
  });
});
