/* test_page.mjs - sdfd's page (GET /) in a real browser: Debian's headless Chromium driven
 * over the DevTools protocol by puppeteer-core, against a real sdfd started here. It picks a
 * mesh, moves the slider, switches modes, probes a point, bakes a volume watching the progress
 * bar reach 100 %, opens the volume's error slice, extracts its surface as a mesh and reads that
 * mesh's report, saves screenshots (page-mesh.png, page.png in SCREENSHOT_DIR, the
 * build directory under meson) and fails on any console error or uncaught exception. */
import { spawn } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import path from 'node:path';
import { createInterface } from 'node:readline';
import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import puppeteer from 'puppeteer-core';

const SDFD = process.env.SDFD ?? 'build/server/sdfd';
const DATA = process.env.SDF_TEST_DATA ?? 'tests/data';
const CHROMIUM = process.env.CHROMIUM ?? '/usr/bin/chromium';
const SHOTS = process.env.SCREENSHOT_DIR ?? '.';

let server, base, browser, page, profile;
const errors = [];

/* sdfd on a free loopback port: the port and readiness come from its JSON log. */
function startServer(...flags) {
  const proc = spawn(SDFD, ['--http', '127.0.0.1:0', '--bin', '127.0.0.1:0', ...flags],
    { stdio: ['ignore', 'ignore', 'pipe'] });
  return new Promise((resolve, reject) => {
    let port;
    const timer = setTimeout(() => reject(new Error('sdfd did not become ready')), 60000);
    createInterface({ input: proc.stderr }).on('line', (line) => {
      let e;
      try {
        e = JSON.parse(line);
      } catch {
        return;
      }
      if (e.event === 'listening' && e.proto === 'http')
        port = e.port;
      if (e.event === 'ready') {
        clearTimeout(timer);
        resolve({ proc, url: `http://127.0.0.1:${port}` });
      }
    });
    proc.on('exit', (code) => reject(new Error(`sdfd exited with ${code}`)));
  });
}

before(async () => {
  ({ proc: server, url: base } = await startServer());
  const put = await fetch(`${base}/v1/meshes/fandisk`,
    { method: 'PUT', body: readFileSync(path.join(DATA, 'fandisk.off')) });
  assert.equal(put.status, 201);
  profile = mkdtempSync(path.join(tmpdir(), 'sdfd-page-'));
  browser = await puppeteer.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      `--user-data-dir=${profile}`],
  });
  page = await browser.newPage();
  await page.setViewport({ width: 1200, height: 900 });
  page.on('console', (m) => {
    if (m.type() === 'error')
      errors.push(`console: ${m.text()} ${JSON.stringify(m.location())}`);
  });
  page.on('pageerror', (e) => errors.push(`exception: ${e.message}`));
  page.on('requestfailed', (r) => errors.push(`request failed: ${r.url()} ${r.failure()?.errorText}`));
});

after(async () => {
  await browser?.close();
  server?.kill('SIGTERM');
  if (profile)
    rmSync(profile, { recursive: true, force: true });
});

const version = () => page.$eval('#slice', (img) => Number(img.dataset.version ?? 0));

/* Do `action`, then wait until the slice shown is a newer one than before it. */
async function newSlice(action) {
  const before = await version();
  await action();
  await page.waitForFunction((v) => Number(document.getElementById('slice').dataset.version ?? 0) > v
    && document.getElementById('slice').complete, { timeout: 60000 }, before);
  const [w, h] = await page.$eval('#slice', (img) => [img.naturalWidth, img.naturalHeight]);
  assert.ok(w > 100 && h > 100, `slice ${w} x ${h}`);
}

test('the page and its files are served from the binary', async () => {
  const index = await fetch(`${base}/`);
  assert.equal(index.status, 200);
  assert.match(index.headers.get('content-type'), /^text\/html/);
  assert.match(await index.text(), /<script type="module" src="\/static\/page.js">/);
  for (const f of ['page.js', 'page.css', 'index.js', 'http.js', 'errors.js', 'wire.js']) {
    const r = await fetch(`${base}/static/${f}`);
    assert.equal(r.status, 200, f);
    const source = path.join(f.startsWith('page') ? '../../../server/page' : '../../../clients/js/src', f);
    assert.equal(await r.text(), readFileSync(new URL(source, import.meta.url), 'utf8'), f);
  }
  assert.equal((await fetch(`${base}/static/nothing.js`)).status, 404);
});

test('pick a mesh, slide, switch modes, probe, bake, view the error', async () => {
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 60000 });
  const names = await page.$$eval('#meshes tbody tr', (rows) => rows.map((r) => r.dataset.name));
  assert.deepEqual(names, ['demo', 'fandisk']);

  await newSlice(() => page.click('#meshes tbody tr[data-name="fandisk"]'));
  const report = await page.$eval('#report', (dl) => dl.textContent);
  assert.match(report, /triangles12946/);
  assert.match(await page.$eval('#view-title', (e) => e.textContent), /fandisk/);

  const at0 = await page.$eval('#at-value', (e) => e.textContent);
  await newSlice(() => page.$eval('#at', (el) => {
    el.value = '300';
    el.dispatchEvent(new Event('input'));
  }));
  const at1 = await page.$eval('#at-value', (e) => e.textContent);
  assert.notEqual(at0, at1);
  await newSlice(() => page.select('#axis', 'x'));
  for (const mode of ['filtered', 'gradient', 'signed']) {
    await newSlice(() => page.select('#mode', mode));
    assert.equal(await page.$eval('#slice', (img) => img.dataset.mode), mode);
  }
  assert.match(await page.$eval('#status', (e) => e.textContent), /signed \d+×\d+/);

  /* probe the middle of the slice: a distance, a closest point and a unit gradient */
  const box = await (await page.$('#slice')).boundingBox();
  await page.mouse.click(box.x + box.width / 2, box.y + box.height * 0.4);
  await page.waitForFunction(() => /distance/.test(document.getElementById('probe').textContent));
  const probe = await page.$eval('#probe', (e) => e.textContent);
  const numbers = (label) => probe.match(new RegExp(`${label}\\s+\\(([^)]*)\\)`))[1].split(',').map(Number);
  const distance = Number(probe.match(/distance\s+(\S+)/)[1]);
  assert.ok(Number.isFinite(distance), probe);
  const [p, c, g] = [numbers('point'), numbers('closest'), numbers('gradient')];
  const gap = Math.hypot(...p.map((x, a) => x - c[a]));
  assert.ok(Math.abs(gap - Math.abs(distance)) < 1e-3 * (1 + gap), probe);
  assert.ok(Math.abs(Math.hypot(...g) - 1) < 1e-3, probe);
  assert.equal(await page.$eval('#marker', (m) => m.hidden), false);
  await page.screenshot({ path: path.join(SHOTS, 'page-mesh.png'), fullPage: true });

  /* bake: the bar moves to 100 % and the volume is listed */
  await page.$eval('#bake [name=volume]', (el) => { el.value = 'fan32'; });
  await page.$eval('#bake [name=resolution]', (el) => { el.value = '40'; });
  /* every text the percentage shows, recorded in the page itself: sampling from here
     misses short-lived values when the browser or a sanitizer build is slow */
  await page.$eval('#bake-percent', (el) => {
    window.percents = [el.textContent];
    new MutationObserver(() => window.percents.push(el.textContent))
      .observe(el, { childList: true, characterData: true, subtree: true });
  });
  await page.click('#bake button');
  await page.waitForFunction(() => document.getElementById('bake-percent').textContent === '100 %',
    { timeout: 120000 });
  assert.equal(await page.$eval('#bake-progress', (e) => e.value), 1);
  const seen = new Set(await page.evaluate(() => window.percents));
  assert.ok(seen.has('100 %') && seen.size >= 2, `the bar showed only ${[...seen]}`);
  await page.waitForSelector('#volumes tbody tr[data-name="fan32"]');
  await newSlice(() => page.click('#volumes tbody tr[data-name="fan32"]'));
  assert.equal(await page.$eval('#slice', (img) => img.dataset.mode), 'error');
  await page.mouse.click(box.x + box.width / 2, box.y + box.height * 0.4);
  await page.waitForFunction(() => /value/.test(document.getElementById('probe').textContent));

  /* the volume's surface as a mesh: listed, selected, its report shown (closed, manifold) */
  assert.equal(await page.$eval('#extract [name=volume]', (el) => el.value), 'fan32');
  await page.$eval('#extract [name=mesh]', (el) => { el.value = 'fan32_surface'; });
  await page.select('#extract [name=method]', 'dual_contouring');
  await newSlice(() => page.click('#extract button'));
  await page.waitForSelector('#meshes tbody tr.selected[data-name="fan32_surface"]');
  assert.equal(await page.$eval('#slice', (img) => img.dataset.mode), 'signed');
  await page.waitForFunction(() => /closedtrue/.test(document.getElementById('report').textContent));
  const surface = await page.$eval('#report', (dl) => dl.textContent);
  assert.match(surface, /edge manifoldtrue/);
  assert.match(surface, /format/);
  assert.match(surface, /triangles\d{4,}/);

  await page.screenshot({ path: path.join(SHOTS, 'page.png'), fullPage: true });
  assert.equal(await page.$eval('#token-form', (f) => f.hidden), true, 'no token asked for');
  assert.deepEqual(errors, []);
});

test('a server with --token --auth-queries: the page asks for the token, then works', async () => {
  const locked = await startServer('--token', 'page-secret', '--auth-queries');
  const tab = await browser.newPage();
  const failures = [];
  tab.on('pageerror', (e) => failures.push(`exception: ${e.message}`));
  tab.on('requestfailed', (r) => failures.push(`request failed: ${r.url()}`));
  try {
    await tab.goto(`${locked.url}/`);
    await tab.waitForSelector('#token-form:not([hidden])', { timeout: 60000 });
    assert.match(await tab.$eval('#status', (e) => e.textContent), /--token/);
    await tab.type('#token', 'wrong');
    await Promise.all([tab.waitForNavigation(), tab.click('#token-form button')]);
    await tab.waitForFunction(() => /refused/.test(document.getElementById('status').textContent),
      { timeout: 60000 });
    await tab.$eval('#token', (el) => { el.value = ''; });
    await tab.type('#token', 'page-secret');
    await Promise.all([tab.waitForNavigation(), tab.click('#token-form button')]);
    await tab.waitForSelector('body[data-ready="1"]', { timeout: 60000 });
    await tab.waitForFunction(() => Number(document.getElementById('slice').dataset.version ?? 0) > 0,
      { timeout: 60000 });
    assert.equal(await tab.$eval('#status', (e) => e.className), '');
    /* a bake needs the token too: it runs to the end */
    await tab.$eval('#bake [name=resolution]', (el) => { el.value = '16'; });
    await tab.click('#bake button');
    await tab.waitForFunction(() => document.getElementById('bake-percent').textContent === '100 %',
      { timeout: 120000 });
    await tab.waitForSelector('#volumes tbody tr[data-name="baked"]');
    assert.deepEqual(failures, []);
  } finally {
    await tab.close();
    locked.proc.kill('SIGTERM');
  }
});
