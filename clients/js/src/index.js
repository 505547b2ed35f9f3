/* index.js - the browser-safe entry of sdfd-client: the HTTP client (fetch only), SdfError
 * and the wire helpers. It imports nothing from node, so bundlers and browsers can load it;
 * node.js adds the binary-protocol client on top. */
export { Client } from './http.js';
export { SdfError } from './errors.js';
export { INTERPOLATIONS, MODES, SIGNS, WORDS, encodeNpy, parseNpy, toPoints } from './wire.js';
