/* node.js - the node entry of sdfd-client: everything the browser entry has, plus
 * BinaryClient (proto/PROTOCOL.md over net.Socket), which browsers cannot open. */
export * from './index.js';
export { BinaryClient } from './binary.js';
