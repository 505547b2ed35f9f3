/* apicheck.test.js - the response check of apicheck.js fails on answers docs/openapi.yaml does
 * not describe (as tests/api/test_apicheck.py shows for apicheck.py): made-up Responses of each
 * kind of violation through checkedFetch, documented ones handed back unchanged, then a real
 * sdfd's answer checked against a document that no longer describes it: the fetch fails, an
 * answer through node:http's request is kept as a violation, and Server.stop() fails. */
import assert from 'node:assert/strict';
import http from 'node:http';
import { test } from 'node:test';
import { Client } from 'sdfd-client';
import { ApiViolation, Document, checkedFetch, checkedRequest, load, use, violations }
  from './apicheck.js';
import { Server } from './harness.js';

const REPORT = {
  name: 'tet', format: 'obj', vertices: 4, input_vertices: 4, triangles: 4,
  bbox: { min: [0, 0, 0], max: [1, 1, 1] }, diagonal: 1.7320508075688772,
  closed: true, edge_manifold: true, self_intersecting: false, flipped: false,
  degenerate_triangles: 0, boundary_edges: 0, nonmanifold_edges: 0,
  misoriented_edges: 0, volume: 0.16666666666666666, sign: 'pseudonormal',
  index_bytes: 472, build_seconds: 0.0007, warnings: 0,
};
const JSON_TYPE = { 'Content-Type': 'application/json' };
const BASE = 'http://127.0.0.1:1';

/* A made-up answer: a body given as an object is sent as its JSON. */
function answer(status, headers, body = null) {
  const bytes = body === null || typeof body === 'string' || body instanceof Uint8Array
    ? body : JSON.stringify(body);
  return new Response(bytes, { status, headers });
}

/* The answer to `method path`, fetched through checkedFetch from a fetch that makes it. */
function fetchAnswer(method, path, response) {
  return checkedFetch(async () => response)(BASE + path, { method });
}

const error = (code) => ({ error: { code, message: 'no' } });

test('documented answers pass, handed back as they came', async () => {
  const cases = [
    ['GET', '/v1/meshes/tet', answer(200, JSON_TYPE, REPORT), REPORT],
    ['PUT', '/v1/meshes/tet?format=obj', answer(201, JSON_TYPE, REPORT), REPORT],
    ['POST', '/v1/meshes/tet/query',
      answer(200, { ...JSON_TYPE, 'X-SDF-Count': '1' }, '{"distance": [-0.0], "gradient": [[1, 0, null]]}'),
      { distance: [-0], gradient: [[1, 0, null]] }],
    ['PATCH', '/v1/meshes/tet',
      answer(405, { ...JSON_TYPE, Allow: 'GET, HEAD, PUT, DELETE' }, error('EMETHOD')),
      error('EMETHOD')],
    ['GET', '/v1/nothing', answer(404, JSON_TYPE, error('ENOTFOUND')), error('ENOTFOUND')],
  ];
  for (const [method, path, response, body] of cases) {
    const got = await fetchAnswer(method, path, response);
    assert.equal(got, response, `${method} ${path}`);
    assert.deepEqual(await got.json(), body, `${method} ${path}: the body is the caller's`);
  }
  for (const [method, response] of [['DELETE', answer(204, JSON_TYPE)], ['HEAD', answer(200, JSON_TYPE)]])
    assert.equal(await fetchAnswer(method, '/v1/meshes/tet', response), response, method);
});

test('each violation is caught and kept', async () => {
  const missing = Object.fromEntries(Object.entries(REPORT).filter(([k]) => k !== 'warnings'));
  const query = { ...JSON_TYPE, 'X-SDF-Count': '1' };
  const cases = {
    'an undocumented key': ['GET', '/v1/meshes/tet', answer(200, JSON_TYPE, { ...REPORT, colour: 'red' })],
    'a missing key': ['GET', '/v1/meshes/tet', answer(200, JSON_TYPE, missing)],
    'a wrong type': ['GET', '/v1/meshes/tet', answer(200, JSON_TYPE, { ...REPORT, closed: 'yes' })],
    'a value outside the enum': ['GET', '/v1/meshes/tet', answer(200, JSON_TYPE, { ...REPORT, sign: 'auto' })],
    'an undocumented status': ['GET', '/v1/meshes/tet', answer(418, JSON_TYPE, {})],
    'an undocumented Content-Type': ['GET', '/v1/meshes/tet', answer(200, { 'Content-Type': 'text/plain' }, 'x')],
    'a missing header': ['POST', '/v1/meshes/tet/query', answer(200, JSON_TYPE, { distance: [1] })],
    "a header's bad value": ['POST', '/v1/meshes/tet/query',
      answer(200, { ...query, 'X-SDF-Count': 'x' }, { distance: [1] })],
    'a result of no mode': ['POST', '/v1/meshes/tet/query', answer(200, query, { distance: [1], triangle: [0] })],
    "an error of another status's code": ['GET', '/v1/meshes/tet', answer(404, JSON_TYPE, error('EINVAL'))],
    'an error body with more': ['GET', '/v1/meshes/tet',
      answer(404, JSON_TYPE, { error: { code: 'ENOTFOUND', message: 'x', hint: 'y' } })],
    'a 405 whose Allow differs': ['PATCH', '/v1/meshes/tet',
      answer(405, { ...JSON_TYPE, Allow: 'GET, HEAD' }, error('EMETHOD'))],
    'an undocumented method answered': ['PATCH', '/v1/meshes/tet', answer(200, JSON_TYPE, {})],
    'an unknown path answered': ['GET', '/v1/nothing', answer(200, JSON_TYPE, {})],
    'a body on a 204': ['DELETE', '/v1/meshes/tet', answer(204, { ...JSON_TYPE, 'Content-Length': '2' })],
    'JSON that is not UTF-8': ['GET', '/v1/meshes/tet',
      answer(404, JSON_TYPE, Buffer.from('{"error": {"code": "ENOTFOUND", "message": "\xff"}}', 'latin1'))],
    'not JSON': ['GET', '/v1/meshes/tet', answer(200, JSON_TYPE, '{')],
  };
  for (const [what, [method, path, response]] of Object.entries(cases)) {
    const before = violations.length;
    await assert.rejects(fetchAnswer(method, path, response), ApiViolation, what);
    assert.equal(violations.length, before + 1, `${what}: kept`);
    assert.ok(violations.at(-1).startsWith(`${method} ${path} answered ${response.status}`), what);
  }
});

/* The document as if sdfd had added MeshReport's `warnings` since. */
function drifted() {
  const doc = load();
  const report = doc.components.schemas.MeshReport;
  delete report.properties.warnings;
  report.required = report.required.filter((k) => k !== 'warnings');
  return new Document(doc);
}

/* GET url through request (node:http's, wrapped): the whole body. */
function get(request, url) {
  return new Promise((resolve, reject) => {
    request(url, (res) => {
      const chunks = [];
      res.on('data', (chunk) => chunks.push(chunk));
      res.on('end', () => resolve(Buffer.concat(chunks)));
    }).on('error', reject).end();
  });
}

test("a real answer outside the document fails its fetch and the server's stop()", async () => {
  const server = await Server.start();
  const client = new Client(server.url);
  const url = `${server.url}/v1/meshes/demo`;
  const request = checkedRequest(http.request);
  assert.equal((await client.mesh('demo')).name, 'demo'); /* the real document */
  assert.equal(JSON.parse(await get(request, url)).name, 'demo');
  const before = violations.length;
  const old = use(drifted());
  try {
    await assert.rejects(client.mesh('demo'), (e) => e instanceof ApiViolation && /warnings/.test(e.message));
    assert.equal(JSON.parse(await get(request, url)).name, 'demo', 'the caller gets the whole body');
  } finally {
    use(old);
  }
  assert.equal(violations.length, before + 2);
  assert.match(violations.at(-1), /^GET \/v1\/meshes\/demo answered 200[^]*warnings/);
  assert.equal((await client.mesh('demo')).name, 'demo');
  await assert.rejects(server.stop(), /answers outside docs\/openapi\.yaml:[^]*warnings/);
});
