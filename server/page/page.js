/* page.js - sdfd's page: lists the meshes (with a mesh's report) and volumes, shows a slice
 * of the selected one with an axis slider and a mode picker, probes the point under a click
 * (distance, closest point and gradient by a JSON query), and bakes a volume with a progress
 * bar that polls the job; a 401 opens a form for sdfd's --token. Every HTTP call goes
 * through the sdfd-client package (clients/js), served by sdfd from its embedded copy under
 * /static/. */
import { Client } from '/static/index.js';

/* sdfd's --token, when it asks for one (a 401), kept for this tab only: sessionStorage, never
 * a cookie, so it leaves with the tab and is sent only by this page's own requests. */
const TOKEN_KEY = 'sdfd-token';
const token = sessionStorage.getItem(TOKEN_KEY) ?? undefined;
const client = new Client(location.origin, token ? { token } : {});
const $ = (id) => document.getElementById(id);
const MODES = { mesh: ['signed', 'filtered', 'gradient'], volume: ['error', 'signed', 'gradient'] };
/* the filtered slice is a page's preview: fewer samples than a query's default 64 keep it
 * interactive */
const PREVIEW_FILTER = { samples: 16 };
const SIZE = 512;

const state = { kind: null, name: null, lo: [0, 0, 0], hi: [1, 1, 1], slice: null, url: null };
let version = 0;

function status(text, error = false) {
  $('status').textContent = text;
  $('status').className = error ? 'error' : '';
}

/* A failed call's message; a 401 also opens the token form. */
function failed(e) {
  if (e.status === 401) {
    $('token-form').hidden = false;
    $('token').focus();
    return status(token ? 'the token was refused: enter sdfd\'s --token above'
      : 'sdfd asks for its --token: enter it above', true);
  }
  status(e.message, true);
}

/* A token entered: kept for the tab, and the page starts again with it. */
function useToken(event) {
  event.preventDefault();
  sessionStorage.setItem(TOKEN_KEY, $('token').value);
  location.reload();
}

const fmt = (x) => (Math.abs(x) >= 1e4 || (Math.abs(x) < 1e-3 && x !== 0) ? x.toExponential(3) : x.toFixed(4));
const triple = (v) => `(${Array.from(v, fmt).join(', ')})`;

function row(tbody, cells, onClick) {
  const tr = document.createElement('tr');
  for (const c of cells) {
    const td = document.createElement('td');
    td.textContent = String(c);
    tr.append(td);
  }
  tr.addEventListener('click', () => {
    for (const other of document.querySelectorAll('tbody tr.selected'))
      other.classList.remove('selected');
    tr.classList.add('selected');
    onClick();
  });
  tbody.append(tr);
  return tr;
}

async function loadMeshes() {
  const tbody = $('meshes').tBodies[0];
  tbody.replaceChildren();
  const meshes = await client.meshes();
  for (const m of meshes)
    row(tbody, [m.name, m.triangles, m.closed ? 'yes' : 'no', m.sign], () => selectMesh(m.name)).dataset.name = m.name;
  return meshes;
}

async function loadVolumes() {
  const tbody = $('volumes').tBodies[0];
  tbody.replaceChildren();
  for (const v of await client.volumes())
    row(tbody, [v.name, v.dims.join('×'), v.order, v.mesh || '-'], () => selectVolume(v)).dataset.name = v.name;
}

function showReport(report) {
  const dl = $('report');
  dl.replaceChildren();
  const keys = ['format', 'vertices', 'triangles', 'closed', 'edge_manifold', 'self_intersecting',
    'flipped', 'boundary_edges', 'nonmanifold_edges', 'volume', 'sign', 'diagonal', 'build_seconds', 'warning'];
  for (const k of keys) {
    if (report[k] === undefined)
      continue;
    const dt = document.createElement('dt');
    const dd = document.createElement('dd');
    dt.textContent = k.replace(/_/g, ' ');
    dd.textContent = typeof report[k] === 'number' && !Number.isInteger(report[k]) ? fmt(report[k]) : String(report[k]);
    dl.append(dt, dd);
  }
  const dt = document.createElement('dt');
  const dd = document.createElement('dd');
  dt.textContent = 'box';
  dd.textContent = `${triple(report.bbox.min)} – ${triple(report.bbox.max)}`;
  dl.append(dt, dd);
}

function setModes(kind) {
  const select = $('mode');
  select.replaceChildren(...MODES[kind].map((m) => new Option(m, m)));
}

async function selectMesh(name) {
  const report = await client.mesh(name);
  showReport(report);
  /* the slice's default bounds: the box grown by a tenth of its longest side (docs/api.md) */
  const lo = report.bbox.min, hi = report.bbox.max;
  const grow = 0.1 * Math.max(...hi.map((h, a) => h - lo[a]));
  Object.assign(state, { kind: 'mesh', name, lo: lo.map((x) => x - grow), hi: hi.map((x) => x + grow) });
  document.querySelector('#bake [name=mesh]').value = name;
  setModes('mesh');
  $('view-title').textContent = `Slice of mesh ${name}`;
  await refresh();
}

async function selectVolume(v) {
  const hi = v.origin.map((o, a) => o + (v.dims[a] - 1) * v.spacing[a]);
  Object.assign(state, { kind: 'volume', name: v.name, lo: v.origin, hi });
  setModes('volume');
  if (!v.mesh) /* uploaded: no mesh to measure the error against */
    $('mode').value = 'signed';
  document.querySelector('#extract [name=volume]').value = v.name;
  $('view-title').textContent = `Slice of volume ${v.name}`;
  await refresh();
}

function atValue() {
  const a = 'xyz'.indexOf($('axis').value);
  return state.lo[a] + (state.hi[a] - state.lo[a]) * Number($('at').value) / 1000;
}

/* One slice request at a time; a change while one is on its way asks for one more after it,
 * so dragging the slider never queues a request per step. */
let busy = false, again = false;
async function refresh() {
  if (!state.name)
    return;
  if (busy) {
    again = true;
    return;
  }
  busy = true;
  try {
    do {
      again = false;
      await render();
    } while (again);
  } catch (e) {
    failed(e);
  } finally {
    busy = false;
  }
}

async function render() {
  const at = atValue(), mode = $('mode').value;
  $('at-value').textContent = `${$('axis').value} = ${fmt(at)}`;
  const started = performance.now();
  const s = await client.slice(state.name, {
    volume: state.kind === 'volume', axis: $('axis').value, at, mode, size: SIZE,
    filter: mode === 'filtered' ? PREVIEW_FILTER : undefined,
  });
  const url = URL.createObjectURL(new Blob([s.bytes], { type: 'image/png' }));
  const img = $('slice');
  await new Promise((resolve, reject) => {
    img.onload = resolve;
    img.onerror = () => reject(new Error('the slice image did not load'));
    img.src = url;
  });
  if (state.url)
    URL.revokeObjectURL(state.url);
  state.url = url;
  state.slice = s;
  $('marker').hidden = true;
  img.dataset.version = String(++version);
  img.dataset.mode = mode;
  status(`${state.kind} ${state.name}: ${mode} ${s.width}×${s.height}, values ${fmt(s.range[0])} … ${fmt(s.range[1])}, ` +
    `lines every ${fmt(s.step)}, ${Math.round(performance.now() - started)} ms`);
}

/* ---- the probe ---- */

async function probe(event) {
  const s = state.slice, img = $('slice');
  if (!s)
    return;
  const rect = img.getBoundingClientRect();
  const i = Math.floor((event.clientX - rect.left) * img.naturalWidth / rect.width);
  const j = Math.floor((event.clientY - rect.top) * img.naturalHeight / rect.height);
  if (i < 0 || j < 0 || i >= s.width || j >= s.height)
    return; /* the legend */
  const p = [0, 1, 2].map((a) => s.first[a] + i * s.right[a] + j * s.down[a]);
  const marker = $('marker');
  marker.style.left = `${(i + 0.5) * rect.width / img.naturalWidth}px`;
  marker.style.top = `${(j + 0.5) * rect.height / img.naturalHeight}px`;
  marker.hidden = false;
  let text;
  if (state.kind === 'mesh') {
    const [c, g] = await Promise.all([
      client.query(state.name, [p], { mode: 'closest', form: 'json' }),
      client.query(state.name, [p], { mode: 'gradient', form: 'json' }),
    ]);
    text = `point     ${triple(p)}\ndistance  ${fmt(c.distance[0])}\nclosest   ${triple(c.closest)}` +
      ` (triangle ${c.triangle[0]})\ngradient  ${triple(g.gradient)}`;
  } else {
    const r = await client.queryVolume(state.name, [p], { gradient: true, form: 'json' });
    text = `point     ${triple(p)}\nvalue     ${fmt(r.distance[0])}\ngradient  ${triple(r.gradient)}`;
  }
  $('probe').textContent = text;
}

/* ---- a volume's surface as a mesh ---- */

/* POST /v1/volumes/{name}/mesh registers the surface as a mesh; the new mesh is then
   selected, so its report (closed, edge-manifold, triangles) shows. */
async function extract(event) {
  event.preventDefault();
  const form = event.target, button = form.querySelector('button');
  const volume = form.volume.value;
  if (!volume)
    return status('pick a volume to extract its surface', true);
  button.disabled = true;
  try {
    const report = await client.extractMesh(volume, { mesh: form.mesh.value, method: form.method.value });
    status(`extracted ${report.triangles} triangles from ${volume} as ${form.mesh.value}`);
    await loadMeshes();
    const tr = $('meshes').querySelector(`tbody tr[data-name="${CSS.escape(form.mesh.value)}"]`);
    tr?.click();
  } catch (e) {
    failed(e);
  } finally {
    button.disabled = false;
  }
}

/* ---- baking ---- */

async function bake(event) {
  event.preventDefault();
  const form = event.target, button = form.querySelector('button');
  const mesh = form.mesh.value;
  if (!mesh)
    return status('pick a mesh to bake', true);
  button.disabled = true;
  $('bake-progress').value = 0;
  $('bake-percent').textContent = '0 %';
  try {
    const job = await client.bake(mesh, {
      volume: form.volume.value, resolution: Number(form.resolution.value), order: Number(form.order.value),
    });
    const done = await client.waitJob(job, {
      interval: 100,
      onProgress: (s) => {
        $('bake-progress').value = s.progress;
        $('bake-percent').textContent = `${s.percent} %`;
      },
    });
    $('bake-progress').value = done.progress;
    $('bake-percent').textContent = `${done.percent} %`;
    status(`baked ${done.volume} from ${done.mesh} in ${done.seconds.toFixed(2)} s`);
    await loadVolumes();
  } catch (e) {
    failed(e);
  } finally {
    button.disabled = false;
  }
}

async function main() {
  $('axis').addEventListener('change', refresh);
  $('at').addEventListener('input', refresh);
  $('mode').addEventListener('change', refresh);
  $('slice').addEventListener('click', (e) => probe(e).catch(failed));
  $('bake').addEventListener('submit', bake);
  $('extract').addEventListener('submit', extract);
  $('token-form').addEventListener('submit', useToken);
  $('token-form').hidden = !token;
  const meshes = await loadMeshes();
  await loadVolumes();
  if (meshes.length) {
    $('meshes').tBodies[0].rows[0].classList.add('selected');
    await selectMesh(meshes[0].name);
  } else {
    status('no meshes loaded: PUT one to /v1/meshes/{name}');
  }
  document.body.dataset.ready = '1';
}

main().catch(failed);
