// index.d.ts - types of sdfd-client's browser entry (src/index.js): the HTTP client, SdfError
// and the wire helpers. Hand-written beside the plain JavaScript; test/types.ts checks them.

export type Mode = 'signed' | 'distance' | 'gradient' | 'closest' | 'filtered' | 'filtered-gradient';
export type Sign = 'auto' | 'pseudonormal' | 'winding' | 'raycast' | 'none';
export type Form = 'octet' | 'json' | 'npy';
/** A volume query's reconstruction (docs/volumes.md, "Evaluation"): "default" is hermite on
 * first-order volumes and trilinear on zero-order ones; hermite needs a first-order volume. */
export type Interpolation = 'default' | 'trilinear' | 'nearest' | 'hermite';

/** Points: a flat Float32Array (or any number array) of 3N coordinates, or [x, y, z] triples. */
export type Points = Float32Array | ArrayLike<number> | ReadonlyArray<readonly [number, number, number] | ArrayLike<number>>;

/** The filtered modes' parameters (docs/filtered.md); each optional. */
export interface FilterParams {
  kernel?: 'gaussian' | 'bump';
  cap?: number;
  a?: number;
  b?: number;
  samples?: number;
  min_samples?: number;
  medial?: number;
  grid?: boolean;
  unsigned?: boolean;
  allow_wide_bump?: boolean;
  sample_gradient?: boolean;
  seed?: number | bigint;
  smooth?: SmoothVolume;
}

export type SmoothVolume = (
  | { sphere: readonly [number, number, number, number] | ArrayLike<number> }
  | { box: readonly [number, number, number, number, number, number] | ArrayLike<number> }
  | { mesh: string }
) & { depth?: number; scale?: number };

/** A query's answer: `distance` always (the filtered value g in the filtered modes, the
 * volume's value for volume queries); flat 3N `gradient` (modes gradient and
 * filtered-gradient, volume queries with gradient); `closest` and `triangle` (mode closest). */
export interface QueryResult {
  count: number;
  distance: Float32Array;
  gradient?: Float32Array;
  closest?: Float32Array;
  triangle?: Uint32Array;
}

export interface RequestOptions {
  signal?: AbortSignal;
}

export interface QueryOptions extends RequestOptions {
  mode?: Mode;
  sign?: Sign;
  filter?: FilterParams;
  /** The request body's form (default "octet"). */
  form?: Form;
  /** The answer's form (default: the body's). */
  accept?: Form;
}

export interface VolumeQueryOptions extends RequestOptions {
  interpolation?: Interpolation;
  gradient?: boolean;
  form?: Form;
  accept?: Form;
}

export interface ClientOptions {
  /** Sent as "Authorization: Bearer <token>" (sdfd's --token). */
  token?: string;
  /** A fetch to use instead of globalThis.fetch. */
  fetch?: typeof fetch;
  /** Headers added to every request. */
  headers?: Record<string, string>;
}

export interface MeshSummary {
  name: string;
  triangles: number;
  closed: boolean;
  sign: string;
}

/** GET /v1/meshes/{name} (docs/api.md, The mesh report). */
export interface MeshReport {
  name: string;
  format: string;
  vertices: number;
  input_vertices: number;
  triangles: number;
  bbox: { min: [number, number, number]; max: [number, number, number] };
  diagonal: number;
  closed: boolean;
  edge_manifold: boolean;
  self_intersecting: boolean;
  flipped: boolean;
  degenerate_triangles: number;
  boundary_edges: number;
  nonmanifold_edges: number;
  misoriented_edges: number;
  volume: number;
  sign: string;
  index_bytes: number;
  build_seconds: number;
  /** how many things the parser accepted with doubt; the first one's message in `warning` */
  warnings: number;
  warning?: string;
  [key: string]: unknown;
}

export type JobState = 'queued' | 'running' | 'done' | 'failed' | 'canceled';

export interface Job {
  id: string;
  href?: string;
  state: JobState;
  progress: number;
  percent?: number;
  mesh: string;
  volume: string;
  seconds?: number;
  /** the replica running it, or that last ran it (null: a shared job not started yet) */
  owner?: string | null;
  /** how many times a replica started it */
  attempts?: number;
  cancel_requested?: boolean;
  error?: { code: string; message: string };
  /** "ops" for volumeOps's jobs */
  kind?: string;
  /** an ops job's input volume */
  source?: string;
  /** field operations, once done: what the paper's validity caveat found (offsets that
   * crossed the medial axis), empty when nothing */
  caveats?: unknown[];
  warning?: string;
  [key: string]: unknown;
}

/** A field operation's name (docs/api.md): redistance, offset r (signed), round r (convex
 * edges), fillet r (concave ones), smooth r (round then fillet). */
export type OpName = 'redistance' | 'offset' | 'round' | 'fillet' | 'smooth';
/** One field operation: { round: 0.05 } or ['round', 0.05]. */
export type Op = { [K in OpName]: { [P in K]: number } }[OpName] | readonly [OpName, number];

/** How field operations run (POST /v1/volumes/{name}/ops and a bake's body); each optional. */
export interface OpsParams {
  solver?: 'sussman' | 'sweep' | 'exact';
  iterations?: number;
  band?: number;
  strict?: boolean;
}

/** volumeOps's options: the output volume's name and OpsParams. */
export interface VolumeOpsOptions extends RequestOptions, OpsParams {
  volume?: string;
}

/** POST /v1/meshes/{name}/bake's body (docs/api.md, Baking); every key optional. */
export interface BakeParams extends OpsParams {
  /** field operations applied to the baked grid before it is stored */
  ops?: readonly Op[];
  volume?: string;
  /** also store the finished volume's surface as this mesh, in the same job */
  mesh?: string;
  bounds?: { min: [number, number, number]; max: [number, number, number] };
  margin?: number;
  resolution?: number | [number, number, number];
  order?: 0 | 1;
  H?: number;
  delta?: number;
  normalize?: 'plane' | 'gradient';
  field?: 'raw' | 'filtered';
  filter?: FilterParams;
  encoding?: 'float32' | 'packed32';
  sign?: Sign;
}

export interface WaitOptions extends RequestOptions {
  /** Milliseconds before an Error named "TimeoutError" (default 600000). */
  timeout?: number;
  /** Milliseconds between polls (default 50). */
  interval?: number;
  onProgress?: (job: Job) => void;
}

/** GET /v1/volumes/{name} (docs/api.md). */
export interface VolumeInfo {
  name: string;
  dims: [number, number, number];
  origin: [number, number, number];
  spacing: [number, number, number];
  order: 0 | 1;
  encoding: 'float32' | 'packed32';
  packed_center: number;
  packed_range: number;
  /** first order's H and delta (0 for zero order) */
  fine_half: number;
  fine_spacing: number;
  normalize: 'plane' | 'gradient';
  filtered: boolean;
  channels: number;
  layout: string;
  dtype: string;
  bytes: number;
  /** the mesh it was baked from and the job that made it ("" for an uploaded volume) */
  mesh: string;
  job: string;
  bake_seconds: number;
  [key: string]: unknown;
}

export type VolumeFormat = 'exr' | 'npy' | 'raw';

export type SurfaceFormat = 'ply' | 'obj' | 'stl' | 'off';

export interface ExtractMeshOptions extends RequestOptions {
  /** The value whose surface is taken (default 0). */
  iso?: number;
  /** Close the surface where it leaves the grid (default false). */
  cap?: boolean;
  format?: SurfaceFormat;
  /** Store the surface as this mesh instead of answering it. */
  mesh?: string;
  /** 'auto' (default: dual contouring for first-order volumes), 'marching_cubes' or
   * 'dual_contouring' (sharp edges kept). */
  method?: 'auto' | 'marching_cubes' | 'dual_contouring';
}

export interface SurfaceFile {
  format: SurfaceFormat;
  bytes: Uint8Array;
  triangles: number;
}

export interface SurfaceArrays {
  /** x, y, z of each vertex */
  vertices: Float32Array;
  /** three vertex indices a triangle, counter-clockwise seen from outside */
  triangles: Uint32Array;
}

export interface VolumeDownload {
  format: VolumeFormat;
  bytes: Uint8Array;
  /** N, M, K from X-SDF-Dims. */
  dims: number[];
  order: number;
  encoding: string;
  /** npy and raw: the node words (Float32Array, or Uint32Array for packed32), K x M x N
   * (x 4 for first order), node (i, j, k) at ((k M + j) N + i) (x 4). */
  values?: Float32Array | Uint32Array;
  shape?: number[];
}

/** The codes of sdfd's refusals (docs/api.md, "Errors"); an answer that is not an error body
 * is "EUNKNOWN". */
export type ErrorCode = 'EINVAL' | 'ENOMEM' | 'EIO' | 'EFORMAT' | 'EPARSE' | 'ETRUNC' | 'ELIMIT'
  | 'EEMPTY' | 'ENONFINITE' | 'EINDEX' | 'EBVH' | 'ENOTFOUND' | 'ECANCELED' | 'EPROTO'
  | 'EUNAUTHORIZED' | 'EMETHOD' | 'ELENGTH' | 'EBUSY' | 'EUNAVAILABLE' | 'ESYNTAX'
  | 'ENOSPACE';

export declare class SdfError extends Error {
  constructor(status: number, code: string, message: string);
  readonly name: 'SdfError';
  /** The HTTP status (400, 401, 404, 413, 422, 429, 503, 507, ...). */
  status: number;
  /** The server's error code (an ErrorCode: "ENOTFOUND", "EINVAL", ...), or "EUNKNOWN". */
  code: string;
}

export declare class Client {
  constructor(url?: string, options?: ClientOptions);
  readonly url: string;

  health(options?: RequestOptions): Promise<{ status: string }>;
  ready(options?: RequestOptions): Promise<{ ready: boolean; status: string }>;
  metrics(options?: RequestOptions): Promise<string>;

  meshes(options?: RequestOptions): Promise<MeshSummary[]>;
  mesh(name: string, options?: RequestOptions): Promise<MeshReport>;
  putMesh(name: string, data: Uint8Array | ArrayBuffer | Blob | string,
    options?: RequestOptions & { format?: 'obj' | 'ply' | 'stl' | 'off' }): Promise<MeshReport & { created: boolean }>;
  putMeshArrays(name: string,
    mesh: { vertices: ArrayLike<number> | number[][]; faces: ArrayLike<number> | number[][] },
    options?: RequestOptions): Promise<MeshReport & { created: boolean }>;
  deleteMesh(name: string, options?: RequestOptions): Promise<void>;
  query(name: string, points: Points, options?: QueryOptions): Promise<QueryResult>;

  bake(name: string, params?: BakeParams, options?: RequestOptions): Promise<Job>;
  /** POST /v1/volumes/{name}/ops: field operations, in order, as a job like a bake. */
  volumeOps(name: string, ops: readonly Op[], options?: VolumeOpsOptions): Promise<Job>;
  /** GET /v1/volumes/{name}/mesh: the surface as arrays, or as a file with `format`;
   * POST with `mesh`: stored as that mesh. */
  extractMesh(name: string, options: ExtractMeshOptions & { mesh: string }): Promise<MeshReport & { created: boolean }>;
  extractMesh(name: string, options: ExtractMeshOptions & { format: SurfaceFormat }): Promise<SurfaceFile>;
  extractMesh(name: string, options?: ExtractMeshOptions): Promise<SurfaceArrays>;
  job(id: number | string, options?: RequestOptions): Promise<Job>;
  jobs(options?: RequestOptions): Promise<Job[]>;
  cancelJob(id: number | string, options?: RequestOptions): Promise<Job>;
  waitJob(job: Job | number | string, options?: WaitOptions): Promise<Job>;

  volumes(options?: RequestOptions): Promise<VolumeInfo[]>;
  volume(name: string, options?: RequestOptions): Promise<VolumeInfo>;
  putVolume(name: string, exr: Uint8Array | ArrayBuffer | Blob,
    options?: RequestOptions): Promise<VolumeInfo & { created: boolean }>;
  deleteVolume(name: string, options?: RequestOptions): Promise<void>;
  download(name: string, options?: RequestOptions & { format?: VolumeFormat }): Promise<VolumeDownload>;
  queryVolume(name: string, points: Points, options?: VolumeQueryOptions): Promise<QueryResult>;
  /** GET .../slice.png of a mesh, or of a volume with `volume: true` (docs/api.md, Slices). */
  slice(name: string, options?: SliceOptions): Promise<Slice>;
}

export type SliceMode = 'signed' | 'distance' | 'filtered' | 'gradient' | 'error';

export interface SliceOptions extends RequestOptions {
  /** a volume's slice (default: a mesh's) */
  volume?: boolean;
  axis?: 'x' | 'y' | 'z';
  at?: number;
  normal?: ArrayLike<number>;
  origin?: ArrayLike<number>;
  /** x0, y0, z0, x1, y1, z1 */
  bounds?: ArrayLike<number>;
  /** pixels along the longer side, 1..2048 (default 512) */
  size?: number;
  mode?: SliceMode;
  sign?: Sign;
  interpolation?: Interpolation;
  step?: number;
  filter?: FilterParams;
  format?: 'png' | 'npy';
}

export interface Slice {
  format: 'png' | 'npy';
  /** the PNG or npy file */
  bytes: Uint8Array;
  width: number;
  height: number;
  /** pixel (i, j) is centred at first + i * right + j * down */
  first: number[];
  right: number[];
  down: number[];
  /** min, max of the finite values */
  range: number[];
  step: number;
  /** npy: height x width values, rows from the top */
  values?: Float32Array;
}

export declare const MODES: Readonly<Record<Mode, number>>;
/** VOLUME_QUERY's code of each interpolation (proto/PROTOCOL.md). */
export declare const INTERPOLATIONS: Readonly<Record<Interpolation, number>>;
export declare const SIGNS: Readonly<Record<Sign, number>>;
/** Words per point of each mode's answer, by mode number. */
export declare const WORDS: readonly number[];

/** Points as a flat Float32Array (a Float32Array itself is returned as it is). */
export declare function toPoints(points: Points): Float32Array;
/** A .npy file of shape (N, 3) float32 holding 3N coordinates. */
export declare function encodeNpy(points: Float32Array): Uint8Array;
/** A .npy file's header and the bytes after it. */
export declare function parseNpy(bytes: Uint8Array | ArrayBuffer): {
  descr: string;
  fortranOrder: boolean;
  shape: number[];
  data: Uint8Array;
};
