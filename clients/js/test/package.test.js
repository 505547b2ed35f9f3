/* package.test.js - the package as others load it: the hand-written .d.ts files type-check
 * against test/types.ts through the "exports" map (tsc from Debian's node-typescript, or
 * TSC), the browser entry reaches no node module (so a bundler can ship it), each condition
 * resolves to its entry, and every file "exports" names is one "files" ships. */
import assert from 'node:assert/strict';
import { execFile } from 'node:child_process';
import { existsSync, readFileSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { promisify } from 'node:util';
import { test } from 'node:test';

const run = promisify(execFile);
const pkgDir = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const pkg = JSON.parse(readFileSync(path.join(pkgDir, 'package.json'), 'utf8'));

test('the .d.ts files type-check against their use (tsc --noEmit, strict)', async () => {
  const tsc = process.env.TSC ?? 'tsc';
  try {
    await run(tsc, ['-p', path.join(pkgDir, 'test', 'tsconfig.json')], { cwd: pkgDir });
  } catch (e) {
    assert.fail(e.code === 'ENOENT' ? `${tsc} not found (Debian: apt-get install node-typescript)`
      : `tsc failed:\n${e.stdout}${e.stderr}`);
  }
});

/* The relative imports reachable from a module, read from its source. */
function imports(file) {
  const src = readFileSync(file, 'utf8');
  return [...src.matchAll(/^\s*(?:import|export)\b[^'"]*?from\s+['"]([^'"]+)['"]/gm),
    ...src.matchAll(/^\s*import\s+['"]([^'"]+)['"]/gm), ...src.matchAll(/\bimport\(\s*['"]([^'"]+)['"]/g)]
    .map((m) => m[1]);
}

function graph(entry) {
  const seen = new Set();
  const specifiers = new Set();
  const visit = (file) => {
    if (seen.has(file))
      return;
    seen.add(file);
    for (const s of imports(file)) {
      specifiers.add(s);
      if (s.startsWith('.'))
        visit(path.resolve(path.dirname(file), s));
    }
  };
  visit(path.join(pkgDir, entry));
  return { files: [...seen], specifiers: [...specifiers] };
}

test('the browser entry imports nothing from node; the node entry adds net', () => {
  const browser = graph('src/index.js');
  assert.deepEqual(browser.specifiers.filter((s) => !s.startsWith('.')), []);
  assert.ok(browser.files.length >= 3);
  const node = graph('src/node.js');
  assert.ok(node.specifiers.includes('node:net'));
});

test('conditions resolve to their entries', async () => {
  const probe = "import('sdfd-client').then((m) => console.log(Object.keys(m).sort().join(' ')))";
  const asNode = (await run(process.execPath, ['-e', probe], { cwd: pkgDir })).stdout.trim().split(' ');
  const asBrowser = (await run(process.execPath, ['--conditions=browser', '-e', probe], { cwd: pkgDir })).stdout.trim().split(' ');
  assert.ok(asNode.includes('BinaryClient') && asNode.includes('Client'));
  assert.ok(!asBrowser.includes('BinaryClient') && asBrowser.includes('Client') && asBrowser.includes('SdfError'));
  assert.deepEqual(asNode.filter((k) => k !== 'BinaryClient'), asBrowser);
});

test('every file "exports" names exists and is shipped by "files"', () => {
  const targets = new Set();
  const walk = (v) => (typeof v === 'string' ? targets.add(v) : Object.values(v).forEach(walk));
  walk(pkg.exports);
  targets.add(pkg.main).add(pkg.types);
  for (const t of targets) {
    assert.ok(existsSync(path.join(pkgDir, t)), `${t} is missing`);
    assert.ok(t === './package.json' || pkg.files.some((f) => t.startsWith(`./${f}`)), `${t} is not in "files"`);
  }
  assert.equal(pkg.engines.node, '>=18');
  assert.deepEqual(pkg.dependencies ?? {}, {});
});
