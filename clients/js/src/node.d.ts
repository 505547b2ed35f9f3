// node.d.ts - types of sdfd-client's node entry (src/node.js): the browser entry's, plus
// BinaryClient for proto/PROTOCOL.md, and a Client that takes a CA for https://. Needs no
// @types/node: nothing here names node's types.
import type { Interpolation, Mode, Points, QueryResult, RequestOptions, Sign, FilterParams } from './index.js';
import { Client as BrowserClient, type ClientOptions } from './index.js';

export * from './index.js';

export interface NodeClientOptions extends ClientOptions {
  /** PEM CA certificate(s) an https:// server's certificate must verify against (node's own
   * CAs without it). Not with `fetch`. */
  ca?: string | Uint8Array;
}

/** The browser entry's Client, plus `ca` (requests then go through node:https). */
export declare class Client extends BrowserClient {
  constructor(url?: string, options?: NodeClientOptions);
}

export interface BinaryClientOptions {
  /** Default "127.0.0.1". */
  host?: string;
  /** sdfd's --bin port; default 9090. */
  port?: number;
  /** Sent in AUTH on every connection (a server with --token and --auth-queries needs it). */
  token?: string;
  /** HELLO's client name. */
  clientName?: string;
  /** Most requests written and not yet answered (default 64, the server's own window). */
  maxInFlight?: number;
  /** Send a request once more on a new connection when its connection died before its
   * reply, or a query when the server refused it as unavailable (503 EUNAVAILABLE, a
   * replica shutting down), and open a new connection closed or reset before its handshake
   * is answered again, three times in all (default true: every message of the protocol
   * only reads). */
  resend?: boolean;
  /** Milliseconds to wait for a connection (default 10000). */
  connectTimeout?: number;
  /** A server started with --bin-tls: TLS 1.2+, the certificate verified (default false). */
  tls?: boolean;
  /** With tls: PEM CA certificate(s) to verify against (node's own CAs without it). */
  ca?: string | Uint8Array;
}

export interface Hello {
  version: number;
  maxPayload: number;
  maxPoints: number;
  server: string;
}

export interface BinaryStats {
  connects: number;
  resent: number;
  /** Writes that filled the socket's buffer, after which writing waited for 'drain'. */
  backpressure: number;
  maxInFlight: number;
}

export declare class BinaryClient {
  constructor(options?: BinaryClientOptions);
  readonly stats: BinaryStats;
  hello(options?: RequestOptions): Promise<Hello>;
  auth(token: string, options?: RequestOptions): Promise<void>;
  meshes(options?: RequestOptions): Promise<Array<{ name: string; triangles: number; closed: boolean; sign: string }>>;
  query(name: string, points: Points,
    options?: RequestOptions & { mode?: Mode; sign?: Sign; filter?: FilterParams }): Promise<QueryResult>;
  queryVolume(name: string, points: Points,
    options?: RequestOptions & { interpolation?: Interpolation; gradient?: boolean }): Promise<QueryResult>;
  close(): Promise<void>;
}
