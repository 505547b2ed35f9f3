/* apicheck.js - every HTTP answer a JS client test receives, checked against
 * docs/openapi.yaml: the port of tests/api/apicheck.py (whose comment is the specification),
 * so that the JavaScript client's tests hold sdfd to its document as the Python tests do.
 *
 * Each answer is matched to the document's operation by path template and method, then
 * checked. Its status must be one the operation documents; its Content-Type one documented for
 * that status; every header that response documents must be present with a value its schema
 * allows (sdfd sends each one it documents); a JSON body must be valid against the response's
 * schema (JSON Schema 2020-12, which OpenAPI 3.1's schemas are) and a body the document gives
 * no content must be empty. A method a documented path lacks must be answered 405 with the
 * error body and an `Allow` header listing exactly the document's methods; a path no template
 * matches, 404 `ENOTFOUND`.
 *
 * checkedFetch wraps a fetch (harness.js wraps globalThis.fetch with it): a JSON body is read
 * from a clone, so the caller gets the response as the server sent it, and a violation rejects
 * the fetch with ApiViolation. checkedRequest wraps node:https's request, which Client's `ca`
 * option sends through instead of fetch: the answer is checked as it ends. Either way the
 * violation is kept in `violations`, which harness.js's Server.stop() reports, so one the code
 * under test caught still fails the test.
 *
 * With SDF_APICHECK_LOG=FILE, each checked answer's method, path template, status and type is
 * appended to FILE, as apicheck.py does (which operations and statuses the tests reach).
 *
 * ajv (v8, its JSON Schema 2020-12 build) and js-yaml come from tests/api/node_modules
 * (tests/api/package-lock.json, installed by .ci/deps): the client itself depends on nothing. */
import fs from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..', '..');
const require = createRequire(path.join(root, 'tests', 'api', 'package.json'));
const Ajv2020 = require('ajv/dist/2020');
const yaml = require('js-yaml');

export const DOCUMENT = path.join(root, 'docs', 'openapi.yaml');
const METHODS = ['get', 'put', 'post', 'delete', 'options', 'head', 'patch', 'trace'];
/* One object, so that its compiled validator is cached like every other schema's. */
const ERROR_SCHEMA = { $ref: '#/components/schemas/Error' };
const LOG = process.env.SDF_APICHECK_LOG; /* a file to note each checked answer in, if set */

/** An answer the document does not describe. */
export class ApiViolation extends Error {
  name = 'ApiViolation';
}

export function load(file = DOCUMENT) {
  return yaml.load(fs.readFileSync(file, 'utf8'));
}

/** 'Application/JSON ; charset=x' -> 'application/json; charset=x' (for comparing). */
export function mediaType(value) {
  const [type, ...params] = (value ?? '').split(';').map((p) => p.trim());
  return [type.toLowerCase(), ...params.filter(Boolean)].join('; ');
}

/* A request path as sdfd routes it: the query string and fragment removed, every %HH decoded
 * but %00 (each byte one character, as apicheck.py's latin-1). */
function routedPath(target) {
  return target.split('?')[0].split('#')[0].replace(/%([0-9A-Fa-f]{2})/g,
    (escape, hex) => (hex === '00' ? escape : String.fromCharCode(parseInt(hex, 16))));
}

/* A path template as a regular expression: each {parameter} one segment. */
function templatePattern(template) {
  const literal = (s) => s.replace(/[.*+?^${}()|[\]\\]/g, '\\$&');
  return new RegExp(`^${template.split(/\{[^}]*\}/).map(literal).join('[^/]*')}$`);
}

/* JSON text of UTF-8 bytes, parsed; throws on bytes that are not UTF-8 as on text not JSON. */
function parseJson(body) {
  return JSON.parse(new TextDecoder('utf-8', { fatal: true }).decode(body));
}

/* The first n bytes of a body as text, quoted, for a report. */
function preview(body, n) {
  return JSON.stringify(new TextDecoder().decode(body.subarray(0, n)));
}

/** An OpenAPI document's paths, matched and checked (see the module's comment). */
export class Document {
  constructor(doc) {
    this.doc = doc;
    /* strict: false lets OpenAPI's own keywords (example, ...) and the copied `components`
     * through; formats are not checked, as apicheck.py's jsonschema does not check them. */
    this.ajv = new Ajv2020({ strict: false, allErrors: true, validateFormats: false });
    this.validators = new Map();
    this.templates = Object.entries(doc.paths).map(([template, item]) =>
      ({ pattern: templatePattern(template), template, item }));
  }

  resolve(node) {
    while (node && typeof node === 'object' && '$ref' in node)
      node = node.$ref.replace(/^#\//, '').split('/').reduce((at, part) => at[part], this.doc);
    return node;
  }

  /** {template, item} of a request target, or {template: null, item: null}. */
  match(target) {
    const p = routedPath(target);
    const found = this.templates.find(({ pattern }) => pattern.test(p));
    return found ?? { template: null, item: null };
  }

  /** The errors of instance against a schema of the document, as text. */
  validate(schema, instance) {
    let validator = this.validators.get(schema);
    if (!validator) {
      /* The root carries the document's components, so '#/components/...' resolves in it. */
      validator = this.ajv.compile({ ...schema, components: this.doc.components });
      this.validators.set(schema, validator);
    }
    if (validator(instance))
      return [];
    const errors = [...validator.errors]
      .sort((a, b) => a.instancePath.localeCompare(b.instancePath));
    return errors.slice(0, 5).map((e) => `${e.instancePath.slice(1) || '(top)'}: `
      + `${e.message} ${JSON.stringify(e.params)}`.slice(0, 300));
  }

  /** Everything wrong with one response, as sentences (empty: it is documented). headers: a
   * Headers; body: the bytes of a JSON body, or null when it was not read (not JSON, or a
   * HEAD). */
  check(method, target, status, headers, body) {
    const { template, item } = this.match(target);
    if (!item)
      return this.checkNoRoute(status, headers, body);
    const op = METHODS.includes(method.toLowerCase()) ? item[method.toLowerCase()] : undefined;
    if (!op)
      return this.checkNoMethod(item, status, headers, body);
    const documented = op.responses[String(status)];
    if (!documented)
      return [`status ${status} is not documented for ${method} ${template}`];
    const response = this.resolve(documented);
    const problems = this.checkHeaders(response, headers);
    if (method === 'HEAD')
      return problems;
    const content = response.content ?? {};
    if (Object.keys(content).length === 0) {
      if (body?.length || Number(headers.get('Content-Length') ?? 0))
        problems.push(`${status} has a body; the document gives it none`);
      return problems;
    }
    const ctype = mediaType(headers.get('Content-Type'));
    const kinds = new Map(Object.entries(content).map(([k, v]) => [mediaType(k), v]));
    if (!kinds.has(ctype))
      return [...problems, `${status} Content-Type ${JSON.stringify(ctype)} is not documented `
        + `(${[...kinds.keys()].sort().join(', ')})`];
    if (body !== null)
      problems.push(...this.checkJson(kinds.get(ctype).schema ?? {}, body));
    return problems;
  }

  checkHeaders(response, headers) {
    const problems = [];
    for (const [name, documented] of Object.entries(response.headers ?? {})) {
      const header = this.resolve(documented);
      let value = headers.get(name);
      if (value === null) {
        problems.push(`header ${name} is missing`);
        continue;
      }
      const schema = header.schema ?? {};
      if (this.resolve(schema).type === 'integer') {
        if (!/^\s*[+-]?[0-9]+\s*$/.test(value)) {
          problems.push(`header ${name}: ${JSON.stringify(value)} is not an integer`);
          continue;
        }
        value = Number(value);
      }
      problems.push(...this.validate(schema, value).map((e) => `header ${name}: ${e}`));
    }
    return problems;
  }

  checkJson(schema, body) {
    let instance;
    try {
      instance = parseJson(body);
    } catch (e) {
      return [`the body is not JSON (${e.message}): ${preview(body, 200)}`];
    }
    return this.validate(schema, instance).map((e) => `body ${e}`);
  }

  errorBody(status, headers, body, code) {
    if (mediaType(headers.get('Content-Type')) !== 'application/json')
      return [`${status} is not a JSON error body`];
    if (body === null)
      return [];
    const problems = this.checkJson(ERROR_SCHEMA, body);
    if (problems.length)
      return problems;
    const got = parseJson(body).error.code;
    return got === code ? [] : [`${status} has code ${got}, not ${code}`];
  }

  checkNoRoute(status, headers, body) {
    if (status !== 404)
      return [`no documented path matches, yet the status is ${status}, not 404`];
    return this.errorBody(status, headers, body, 'ENOTFOUND');
  }

  checkNoMethod(item, status, headers, body) {
    if (status !== 405)
      return [`the method is not documented for this path, yet the status is ${status}`];
    const documented = METHODS.filter((m) => m in item).map((m) => m.toUpperCase()).sort();
    const allow = [...new Set((headers.get('Allow') ?? '').split(',').map((m) => m.trim())
      .filter(Boolean))].sort();
    const problems = allow.join() === documented.join() ? [] : [
      `405's Allow is ${JSON.stringify(allow)}; the document has ${JSON.stringify(documented)}`];
    return [...problems, ...this.errorBody(status, headers, body, 'EMETHOD')];
  }
}

let current = null;
/** Every violation seen, in order (harness.js's Server reports those since it started). */
export const violations = [];

export function document() {
  current ??= new Document(load());
  return current;
}

/** Check against `doc` (a Document) from now on; returns the one used until now. */
export function use(doc) {
  const old = current;
  current = doc;
  return old;
}

/* Checks one answer: notes it in the log, keeps a violation and returns its text (else null). */
function record(method, target, status, headers, body) {
  const doc = document();
  const problems = doc.check(method, target, status, headers, body);
  if (LOG)
    fs.appendFileSync(LOG, `${method} ${doc.match(target).template ?? 'None'} ${status} `
      + `${mediaType(headers.get('Content-Type'))}\n`);
  if (problems.length === 0)
    return null;
  let text = `${method} ${target} answered ${status}, which docs/openapi.yaml does not `
    + `describe:\n  ${problems.join('\n  ')}`;
  if (body?.length)
    text += `\n  body: ${preview(body, 500)}`;
  violations.push(text);
  return text;
}

/* Should the body of this answer be read for the check (a JSON one, not to a HEAD)? */
function readsBody(method, headers) {
  return method !== 'HEAD' && mediaType(headers.get('Content-Type')) === 'application/json';
}

/** `fetch`, each of whose answers is checked: a violation rejects with ApiViolation. */
export function checkedFetch(fetch) {
  return async (input, init = {}) => {
    const response = await fetch(input, init);
    const method = (init.method ?? input.method ?? 'GET').toUpperCase();
    const url = new URL(input.url ?? String(input));
    const body = readsBody(method, response.headers)
      ? new Uint8Array(await response.clone().arrayBuffer()) : null;
    const violation = record(method, url.pathname + url.search, response.status,
      response.headers, body);
    if (violation)
      throw new ApiViolation(violation);
    return response;
  };
}

/** node:http(s)'s `request`, each of whose answers is checked as it ends. A violation is only
 * kept in `violations` (Server.stop() reports it): the answer arrived whole, so there is no
 * error of the request's own to give its caller. */
export function checkedRequest(request) {
  return function checked(...args) {
    const req = request.apply(this, args);
    /* prepended, so its listeners come first: the answer is checked before the caller's
     * 'end' handler runs, and they are added in the same tick as the caller's, so both see
     * every chunk */
    req.prependListener('response', (res) => {
      const headers = new Headers();
      for (const [name, value] of Object.entries(res.headers))
        for (const one of [].concat(value))
          headers.append(name, one);
      const chunks = [];
      if (readsBody(req.method, headers))
        res.on('data', (chunk) => chunks.push(chunk));
      res.on('end', () => record(req.method, req.path, res.statusCode, headers,
        readsBody(req.method, headers) ? new Uint8Array(Buffer.concat(chunks)) : null));
    });
    return req;
  };
}
