/* nodehttp.js - node's Client: the browser entry's (http.js), plus a `ca` option for
 * https:// URLs. Node's fetch takes no CA, so with `ca` the requests go through node:https
 * (one kept-alive agent that verifies the server against that CA and its host name, TLS 1.2+)
 * behind a fetch-shaped function; http.js sees no difference. */
import https from 'node:https';
import { Client as BaseClient } from './http.js';

/* fetch(url, {method, headers, body, signal}) over node:https with `agent`. A failed
 * connection rejects with a TypeError, as fetch's does (http.js retries those once). */
function httpsFetch(agent) {
  return async (url, { method = 'GET', headers = {}, body, signal } = {}) => {
    if (body instanceof Blob)
      body = new Uint8Array(await body.arrayBuffer());
    return send(agent, url, method, headers, body, signal);
  };
}

function send(agent, url, method, headers, body, signal) {
  return new Promise((resolve, reject) => {
    const req = https.request(url, { method, headers, agent, signal }, (res) => {
      const chunks = [];
      res.on('data', (c) => chunks.push(c));
      res.on('error', reject);
      res.on('end', () => {
        const empty = res.statusCode === 204 || res.statusCode === 304 || method === 'HEAD';
        const h = new Headers();
        for (const [k, v] of Object.entries(res.headers))
          for (const one of [].concat(v))
            h.append(k, one);
        resolve(new Response(empty ? null : Buffer.concat(chunks),
          { status: res.statusCode, statusText: res.statusMessage, headers: h }));
      });
    });
    req.on('error', (e) => reject(signal?.aborted ? signal.reason
      : Object.assign(new TypeError(`fetch failed: ${e.message}`), { cause: e })));
    req.end(body === undefined || body === null ? undefined
      : typeof body === 'string' ? body : Buffer.from(body.buffer ?? body, body.byteOffset ?? 0, body.byteLength));
  });
}

export class Client extends BaseClient {
  /**
   * @param {string} [url] e.g. "http://127.0.0.1:8080", or "https://HOST:PORT"
   * @param {{token?: string, fetch?: typeof fetch, headers?: Record<string, string>,
   *   ca?: string | Uint8Array}} [options] `ca`: PEM CA certificate(s) the https server's
   *   certificate must verify against (node's own CAs without it)
   */
  constructor(url = 'http://127.0.0.1:8080', options = {}) {
    if (options.ca !== undefined) {
      if (!String(url).startsWith('https://'))
        throw new TypeError('ca is for https:// URLs');
      if (options.fetch)
        throw new TypeError('give ca or fetch, not both');
      const agent = new https.Agent({ keepAlive: true, ca: options.ca, minVersion: 'TLSv1.2' });
      options = { ...options, fetch: httpsFetch(agent) };
    }
    super(url, options);
  }
}
