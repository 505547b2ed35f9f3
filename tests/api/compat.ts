// compat.ts - compiled (never run) by types.sh: the JS client's hand-written types
// (clients/js/src/index.d.ts) against the types openapi-typescript generates from
// docs/openapi.yaml ('sdfd-openapi', a path types.sh maps to the generated file). Each
// check<...>() is a compile error when its two sides disagree:
//   - the names the client takes are the document's (modes, signs, interpolations, ...);
//   - the fields the client names are the document's fields, no more and no fewer;
//   - every answer the document allows fits the client's type of it;
//   - what the client sends (its scalar options) fits the document's request bodies.
// Client inputs that are broader than the wire on purpose (ArrayLike points and boxes, a
// bigint seed, [name, r] operations) are converted by the client and left out.
import type { components } from 'sdfd-openapi';
import type * as C from '../../clients/js/src/index.js';

type S = components['schemas'];
type P = components['parameters'];

type Same<A, B> = [A] extends [B] ? ([B] extends [A] ? true : false) : false;
type Fits<A, B> = [A] extends [B] ? true : false;
/** An interface's declared keys, without its index signature. */
type KnownKeys<T> = keyof {
  [K in keyof T as string extends K ? never : number extends K ? never : K]: T[K]
};
/** The keys of every member of a union. */
type KeysOfUnion<T> = T extends unknown ? keyof T : never;
declare function check<T extends true>(): void;

// @ts-expect-error the helpers do fail on different types (else every check could pass vacuously)
check<Same<C.Mode, S['Sign']>>();
// @ts-expect-error ... and on a type that does not fit
check<Fits<{ sign: string }, { sign: 'auto' }>>();

// names
check<Same<C.Mode, S['QueryMode']>>();
check<Same<C.Sign, S['Sign']>>();
check<Same<C.Interpolation, S['Interpolation']>>();
check<Same<C.JobState, S['JobState']>>();
check<Same<C.ErrorCode, S['ErrorCode']>>();
check<Same<NonNullable<C.FilterParams['kernel']>, S['Kernel']>>();
check<Same<C.OpName, KeysOfUnion<S['Op']>>>();
check<Same<NonNullable<C.OpsParams['solver']>, S['Solver']>>();
check<Same<C.SliceMode, P['MeshSliceMode'] | P['VolumeSliceMode']>>();
check<Same<NonNullable<C.SliceOptions['axis']>, P['SliceAxis']>>();
check<Same<NonNullable<C.SliceOptions['format']>, P['SliceFormat']>>();
check<Same<C.VolumeFormat, P['VolumeFileFormat']>>();
check<Same<C.SurfaceFormat, P['SurfaceFormat']>>();
check<Same<NonNullable<C.ExtractMeshOptions['method']>, P['SurfaceMethod']>>();
check<Same<C.Form | 'npy', 'octet' | 'json' | 'npy'>>();
type PutMeshOptions = NonNullable<Parameters<C.Client['putMesh']>[2]>;
check<Fits<NonNullable<PutMeshOptions['format']>, P['MeshFormat']>>();
check<Same<NonNullable<C.BakeParams['normalize']>, NonNullable<S['BakeRequest']['normalize']>>>();
check<Same<NonNullable<C.BakeParams['encoding']>, NonNullable<S['BakeRequest']['encoding']>>>();
check<Same<NonNullable<C.BakeParams['field']>, NonNullable<S['BakeRequest']['field']>>>();
check<Same<NonNullable<C.BakeParams['order']>, NonNullable<S['BakeRequest']['order']>>>();
check<Same<C.VolumeInfo['normalize'], S['VolumeInfo']['normalize']>>();
check<Same<C.VolumeInfo['encoding'], S['VolumeInfo']['encoding']>>();

// fields
check<Same<KnownKeys<C.MeshReport>, keyof S['MeshReport']>>();
check<Same<keyof C.MeshSummary, keyof S['MeshSummary']>>();
check<Same<KnownKeys<C.Job>, keyof S['Job']>>();
check<Same<KnownKeys<C.VolumeInfo>, keyof S['VolumeInfo']>>();
check<Same<keyof C.FilterParams, keyof S['Filter']>>();
check<Same<KeysOfUnion<C.SmoothVolume>, keyof S['Smooth']>>();
check<Same<keyof C.BakeParams, keyof S['BakeRequest']>>();
check<Same<keyof C.OpsParams, keyof S['OpsOptions']>>();
check<Same<Exclude<keyof C.VolumeOpsOptions, keyof C.RequestOptions>,
  Exclude<keyof S['OpsRequest'], 'ops'>>>();

// answers fit the client's types of them
check<Fits<S['MeshSummary'], C.MeshSummary>>();
check<Fits<S['MeshReport'], C.MeshReport>>();
check<Fits<S['Job'], C.Job>>();
check<Fits<S['VolumeInfo'], C.VolumeInfo>>();
check<Fits<S['Error']['error']['code'], C.ErrorCode>>();

// what the client sends fits the requests
check<Fits<Omit<C.FilterParams, 'seed' | 'smooth'>, Omit<S['Filter'], 'seed' | 'smooth'>>>();
check<Fits<Omit<C.BakeParams, 'ops' | 'filter'>, Omit<S['BakeRequest'], 'ops' | 'filter'>>>();
check<Fits<C.OpsParams, S['OpsOptions']>>();
check<Fits<{ [K in C.OpName]: { [Q in K]: number } }[C.OpName], S['Op']>>();
