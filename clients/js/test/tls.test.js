/* tls.test.js - the clients against an sdfd with --tls-cert, --tls-key and --bin-tls, with a
 * CA and certificate made here by certtool (gnutls-bin, in .ci/deps): Client on https:// with
 * `ca` and BinaryClient with `tls: true, ca` answer the same bits as a plain sdfd, and a
 * certificate from another CA is refused by both. Client's https answers (node:https, not
 * fetch) are checked against docs/openapi.yaml too: harness.js wraps node:https's request. */
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { after, before, test } from 'node:test';
import { BinaryClient, Client } from 'sdfd-client';
import { Server, randomPoints, sameBits } from './harness.js';

const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'sdfd-js-tls-'));

function certtool(...args) {
  execFileSync('certtool', args, { stdio: 'ignore' });
}

function makeCa(name) {
  const [key, cert, tmpl] = ['key', 'pem', 'tmpl'].map((e) => path.join(dir, `${name}.${e}`));
  fs.writeFileSync(tmpl, `cn = "${name}"\nca\ncert_signing_key\nexpiration_days = 2\n`);
  certtool('--generate-privkey', '--key-type=ecdsa', '--outfile', key);
  certtool('--generate-self-signed', '--load-privkey', key, '--template', tmpl, '--outfile', cert);
  return { cert, key };
}

function makeServerCert(ca) {
  const [key, cert, tmpl] = ['key', 'pem', 'tmpl'].map((e) => path.join(dir, `server.${e}`));
  fs.writeFileSync(tmpl, 'cn = "localhost"\ndns_name = "localhost"\nip_address = "127.0.0.1"\n'
    + 'tls_www_server\nsigning_key\nencryption_key\nexpiration_days = 2\n');
  certtool('--generate-privkey', '--key-type=ecdsa', '--outfile', key);
  certtool('--generate-certificate', '--load-privkey', key, '--load-ca-certificate', ca.cert,
    '--load-ca-privkey', ca.key, '--template', tmpl, '--outfile', cert);
  return { cert, key };
}

let tlsServer, plain, ca, otherCa;

before(async () => {
  const caFiles = makeCa('ca');
  const served = makeServerCert(caFiles);
  ca = fs.readFileSync(caFiles.cert, 'utf8');
  otherCa = fs.readFileSync(makeCa('other-ca').cert, 'utf8');
  tlsServer = await Server.start(['--tls-cert', served.cert, '--tls-key', served.key, '--bin-tls']);
  plain = await Server.start();
});

after(async () => {
  /* both stopped, even when one's stop() throws (answers outside docs/openapi.yaml) */
  const stopped = await Promise.allSettled([tlsServer?.stop(), plain?.stop()]);
  fs.rmSync(dir, { recursive: true, force: true });
  for (const s of stopped)
    if (s.status === 'rejected')
      throw s.reason;
  assert.deepEqual(stopped.map((s) => s.value), [0, 0]);
});

test('https with ca and binary over TLS answer the plain bits', async () => {
  const points = randomPoints(3000, 11, -3, 3);
  const want = await new Client(plain.url).query('demo', points, { mode: 'gradient', form: 'octet' });
  const https = new Client(`https://127.0.0.1:${tlsServer.ports.http}`, { ca });
  for (const form of ['octet', 'npy', 'json']) {
    const got = await https.query('demo', points, { mode: 'gradient', form });
    assert.ok(sameBits(got.distance, want.distance), form);
    assert.ok(sameBits(got.gradient, want.gradient), form);
  }
  assert.equal((await https.health()).status, 'ok');
  const b = new BinaryClient({ port: tlsServer.binPort, tls: true, ca });
  try {
    const many = await Promise.all([0, 1, 2].map(() => b.query('demo', points, { mode: 'gradient' })));
    for (const r of many) {
      assert.ok(sameBits(r.distance, want.distance));
      assert.ok(sameBits(r.gradient, want.gradient));
    }
    assert.equal((await b.hello()).version, 1);
  } finally {
    await b.close();
  }
});

test('a certificate from another CA is refused', async () => {
  const https = new Client(`https://127.0.0.1:${tlsServer.ports.http}`, { ca: otherCa });
  await assert.rejects(https.health(), (e) => e instanceof TypeError
    && e.cause?.code === 'UNABLE_TO_VERIFY_LEAF_SIGNATURE');
  const b = new BinaryClient({ port: tlsServer.binPort, tls: true, ca: otherCa, resend: false });
  try {
    await assert.rejects(b.hello(), (e) => e.code === 'UNABLE_TO_VERIFY_LEAF_SIGNATURE');
  } finally {
    await b.close();
  }
});

test('ca needs https:// or tls: true', () => {
  assert.throws(() => new Client('http://127.0.0.1:1', { ca }), TypeError);
  assert.throws(() => new BinaryClient({ port: 1, ca }), TypeError);
});
