/* node.js - the node entry of sdfd-client: everything the browser entry has, plus
 * BinaryClient (proto/PROTOCOL.md over net.Socket or TLS), which browsers cannot open, and a
 * Client that also takes a CA for https:// (it shadows the browser entry's). */
export * from './index.js';
export { BinaryClient } from './binary.js';
export { Client } from './nodehttp.js';
