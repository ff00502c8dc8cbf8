// The page `slamvdb serve` answers at / (its script at /assets/serve.js): esbuild bundles this file
// with three.js at build time and the server embeds the bundle (src/slamvdb/server/web_assets.cpp),
// so the page needs nothing but the server. It draws GET /api/points (chunks per submap, each placed
// by its T_world_submap, at the finest level of detail within the point budget), colours points by
// class with a layer toggle per class, runs a text question (GET /api/points?query=) as a heat map
// with a colour bar, and shows what the map holds at a clicked point (POST /api/at). In live mode
// (`map|slam --serve`: /api/info has "live") it follows GET /api/events without reloading: the
// chunks of new and growing submaps are fetched (GET /api/points?submap=ID), moved submaps are
// re-placed by their new T_world_submap (nothing fetched), a merged submap's chunks are replaced by
// those of the submap it went into, an unloaded one's are kept, and the mapping progress is shown.
import * as THREE from 'three';
import { applyMerges, applyMoves, chunksDroppedOnResync, replacedBy, submapsToFetch, trackMemory } from './live_changes.js';
import { orbitView } from './orbit_view.js';

const NONE = 255;
const BACKGROUND = 0x101418;
// A perceptual ramp from cold to hot (dark blue, purple, red, orange, yellow): the heat map.
const HEAT_STOPS = [[13, 8, 135], [126, 3, 168], [204, 71, 120], [248, 149, 64], [240, 249, 33]];
const PALETTE = [[0, 166, 81], [230, 25, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48], [145, 30, 180],
                 [70, 240, 240], [240, 50, 230], [210, 245, 60], [250, 190, 212], [0, 128, 128], [170, 110, 40]];

function heat(t) {
  const x = Math.min(Math.max(t, 0), 1) * (HEAT_STOPS.length - 1);
  const i = Math.min(Math.floor(x), HEAT_STOPS.length - 2);
  const f = x - i;
  return HEAT_STOPS[i].map((c, k) => Math.round(c + (HEAT_STOPS[i + 1][k] - c) * f));
}

// GET /api/points's bytes (docs/openapi.yaml): the meta JSON and the chunks as typed-array views.
export function decodePoints(buffer) {
  const view = new DataView(buffer);
  const magic = String.fromCharCode(...new Uint8Array(buffer, 0, 4));
  if (magic !== 'SVPT' || view.getUint16(4, true) !== 1) throw new Error('not a version 1 /api/points answer');
  const flags = view.getUint16(6, true);
  const count = view.getUint32(8, true);
  const metaLength = view.getUint32(12, true);
  const meta = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 16, metaLength)));
  let at = 16 + metaLength;
  const chunks = [];
  for (let c = 0; c < count; ++c) {
    const submap = view.getInt32(at, true);
    const T = new Float32Array(12);
    for (let k = 0; k < 12; ++k) T[k] = view.getFloat32(at + 8 + 4 * k, true);
    const origin = [0, 1, 2].map((k) => view.getFloat32(at + 56 + 4 * k, true));
    const step = view.getFloat32(at + 68, true);
    const n = view.getUint32(at + 72, true);
    const q = new Uint16Array(buffer, at + 76, 3 * n);
    const values = new Uint8Array(buffer, at + 76 + 6 * n, n);
    chunks.push({ submap, T, origin, step, n, q, values });
    at += 76 + 7 * n;
    at = Math.ceil(at / 4) * 4;
  }
  return { flags, meta, chunks };
}

// A chunk's name across answers: its submap and its octree node's corner.
const chunkKey = (chunk) => `${chunk.submap}:${chunk.origin.join(',')}`;

// T_world_submap as the 4 x 4 rows of /api/submaps -> the chunk's 12 floats (rows 0..2).
const rowsToT = (rows) => Float32Array.from(rows.slice(0, 3).flat());

// T_world_submap * translate(origin) * scale(step): the chunk's quantised positions are drawn as they come.
function chunkMatrix(chunk) {
  const T = chunk.T;
  const world = new THREE.Matrix4().set(T[0], T[1], T[2], T[3], T[4], T[5], T[6], T[7], T[8], T[9], T[10], T[11], 0, 0, 0, 1);
  const local = new THREE.Matrix4().makeTranslation(...chunk.origin).multiply(new THREE.Matrix4().makeScale(chunk.step, chunk.step, chunk.step));
  return world.multiply(local);
}

async function fetchPoints(params) {
  const response = await fetch(`/api/points?${new URLSearchParams(params)}`);
  if (!response.ok) {
    const body = await response.json();
    const error = new Error(body.error ? body.error.message : `HTTP ${response.status}`);
    error.status = response.status;
    throw error;
  }
  return decodePoints(await response.arrayBuffer());
}

function element(tag, className, text) {
  const e = document.createElement(tag);
  if (className) e.className = className;
  if (text !== undefined) e.textContent = text;
  return e;
}

async function main() {
  const info = await (await fetch('/api/info')).json();
  // The finest level of detail that fits the point budget.
  let lod = 0;
  let answer;
  for (;; ++lod) {
    try {
      answer = await fetchPoints({ lod });
      break;
    } catch (error) {
      if (error.status !== 413 || lod >= 8) throw error;
    }
  }
  const classes = (answer.meta.classes || []).map((c, k) => ({ name: c.name, rgb: c.rgb || PALETTE[k % PALETTE.length] }));
  const classRgb = (v) => (v === NONE || v >= classes.length ? [128, 128, 128] : classes[v].rgb);

  const scene = new THREE.Scene();
  scene.background = new THREE.Color(BACKGROUND);
  const material = new THREE.PointsMaterial({
    size: (answer.meta.voxel_size * 2 ** lod) / Math.tan((25 * Math.PI) / 180), vertexColors: true, sizeAttenuation: true,
  });
  // One Points object per (chunk, class): a class layer is shown or hidden as a whole.
  const layers = [];
  const hidden = new Set();
  const addChunks = (chunks) => {  // returns their bounds (world)
    const bounds = new THREE.Box3();
    for (const chunk of chunks) {
      const matrix = chunkMatrix(chunk);
      const byValue = new Map();
      for (let i = 0; i < chunk.n; ++i) {
        if (!byValue.has(chunk.values[i])) byValue.set(chunk.values[i], []);
        byValue.get(chunk.values[i]).push(i);
      }
      for (const [value, list] of byValue) {
        const indices = Uint32Array.from(list);
        const q = new Uint16Array(3 * indices.length);
        indices.forEach((i, k) => q.set(chunk.q.subarray(3 * i, 3 * i + 3), 3 * k));
        const geometry = new THREE.BufferGeometry();
        geometry.setAttribute('position', new THREE.BufferAttribute(q, 3));
        geometry.setAttribute('color', new THREE.BufferAttribute(new Uint8Array(3 * indices.length), 3, true));
        const points = new THREE.Points(geometry, material);
        // As position, rotation and scale (a rigid pose times a uniform scale decomposes exactly), so
        // that the raycaster's point threshold is scaled into the chunk's units.
        matrix.decompose(points.position, points.quaternion, points.scale);
        points.updateMatrixWorld(true);
        points.visible = !hidden.has(value);
        geometry.computeBoundingBox();
        bounds.union(geometry.boundingBox.clone().applyMatrix4(matrix));
        scene.add(points);
        layers.push({ points, chunk, key: chunkKey(chunk), value, indices });
      }
    }
    return bounds;
  };
  const bounds = addChunks(answer.chunks);
  // Colours are given in sRGB; three.js renders in linear space and encodes sRGB on output, so
  // the attributes hold linear values (else every colour would come out lighter than its legend).
  const linear = (rgb) => {
    const c = new THREE.Color().setRGB(rgb[0] / 255, rgb[1] / 255, rgb[2] / 255, THREE.SRGBColorSpace);
    return [c.r, c.g, c.b];
  };
  const heatTable = Array.from({ length: 256 }, (_, v) => linear(v === NONE ? [60, 60, 60] : heat(v / 254)));
  const classTable = Array.from({ length: 256 }, (_, v) => linear(classRgb(v)));
  // scores: a score answer's chunks by chunkKey (heat map; a chunk drawn since the question: no
  // score), or null (classes).
  const paint = (scores, only = layers) => {
    for (const layer of only) {
      const colour = layer.points.geometry.getAttribute('color');
      const scored = scores && scores.get(layer.key);
      layer.indices.forEach((i, k) => {
        const rgb = scores ? heatTable[scored ? scored.values[i] : NONE] : classTable[layer.value];
        colour.setXYZ(k, rgb[0], rgb[1], rgb[2]);
      });
      colour.needsUpdate = true;
    }
  };
  paint(null);

  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(window.innerWidth, window.innerHeight);
  document.body.appendChild(renderer.domElement);
  const centre = bounds.isEmpty() ? new THREE.Vector3() : bounds.getCenter(new THREE.Vector3());
  const radius = bounds.isEmpty() ? 10 : Math.max(bounds.getSize(new THREE.Vector3()).length() / 2, 1);
  const eye = new THREE.Vector3(centre.x - 0.2 * radius, centre.y - 0.9 * radius, centre.z + 1.6 * radius);
  const { camera, controls, render } = orbitView(renderer, scene, centre, eye, radius);

  // The panel: facts, the question box, the colour bar, class layers, the clicked point.
  const panel = document.getElementById('slamvdb-panel');
  panel.appendChild(element('div', 'title', 'slamvdb serve'));
  const simulated = info.encoder && info.encoder.simulated ? ' (SIMULATED text encoder)' : '';
  const facts = element('div', '');
  const showFacts = (points) => { facts.textContent = `${points.toLocaleString()} points at lod ${lod}, ${answer.meta.voxel_size} m voxels${simulated}`; };
  showFacts(answer.meta.points);
  panel.appendChild(facts);
  const progress = element('div', 'progress');
  progress.id = 'slamvdb-progress';
  panel.appendChild(progress);
  const form = element('form');
  const input = element('input');
  input.id = 'slamvdb-query';
  input.placeholder = 'ask the map, e.g. tall grass';
  form.appendChild(input);
  panel.appendChild(form);
  const status = element('div', 'status');
  panel.appendChild(status);
  const bar = element('div', 'colour-bar');
  bar.style.background = `linear-gradient(to right, ${HEAT_STOPS.map((c) => `rgb(${c.join(',')})`).join(', ')})`;
  const barLabels = element('div', 'colour-bar-labels');
  barLabels.innerHTML = '<span></span><span></span><span></span>';
  bar.hidden = barLabels.hidden = true;
  panel.appendChild(bar);
  panel.appendChild(barLabels);
  const layerRows = [...classes.map((c, k) => [k, c.name, c.rgb]), [NONE, 'no class', [128, 128, 128]]];
  for (const [value, name, rgb] of classes.length ? layerRows : []) {
    const row = element('label', 'legend');
    const box = element('input');
    box.type = 'checkbox';
    box.checked = true;
    box.dataset.value = value;
    box.addEventListener('change', () => {
      if (box.checked) hidden.delete(value); else hidden.add(value);
      for (const layer of layers) layer.points.visible = !hidden.has(layer.value);
      render();
    });
    const swatch = element('span', 'swatch');
    swatch.style.background = `rgb(${rgb.join(',')})`;
    row.append(box, swatch, document.createTextNode(name));
    panel.appendChild(row);
  }
  const picked = element('div', 'picked');
  picked.id = 'slamvdb-picked';
  panel.appendChild(picked);

  const state = { ready: true, points: answer.meta.points, lod, canvas: renderer.domElement, query: null, scores: null };
  form.addEventListener('submit', async (event) => {
    event.preventDefault();
    const text = input.value.trim();
    try {
      if (!text) {
        state.scores = null;
        paint(null);
        bar.hidden = barLabels.hidden = true;
        status.textContent = '';
      } else {
        status.textContent = `asking "${text}"...`;
        const scored = await fetchPoints({ lod, query: text });
        state.scores = new Map(scored.chunks.map((c) => [chunkKey(c), c]));
        paint(state.scores);
        barLabels.children[0].textContent = scored.meta.score.lo.toFixed(2);
        barLabels.children[1].textContent = `similarity to "${text}"`;
        barLabels.children[2].textContent = scored.meta.score.hi.toFixed(2);
        bar.hidden = barLabels.hidden = false;
        state.scoreRange = [scored.meta.score.lo, scored.meta.score.hi];
        status.textContent = '';
      }
    } catch (error) {
      status.textContent = error.message;
    }
    state.query = text;
    render();
  });

  // A click: the nearest drawn point under the cursor, and what the map holds there.
  const raycaster = new THREE.Raycaster();
  raycaster.params.Points.threshold = answer.meta.voxel_size * 2 ** lod;
  renderer.domElement.addEventListener('click', async (event) => {
    const rect = renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1, -((event.clientY - rect.top) / rect.height) * 2 + 1);
    raycaster.setFromCamera(ndc, camera);
    const hits = raycaster.intersectObjects(layers.map((l) => l.points).filter((p) => p.visible), false);
    if (!hits.length) return;
    const hit = hits.sort((a, b) => a.distanceToRay - b.distanceToRay || a.distance - b.distance)[0];
    const layer = layers.find((l) => l.points === hit.object);
    const world = new THREE.Vector3().fromBufferAttribute(hit.object.geometry.getAttribute('position'), hit.index).applyMatrix4(hit.object.matrixWorld);
    const response = await fetch('/api/at', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify({ points: [[world.x, world.y, world.z]] }) });
    const row = (await response.json()).results[0];
    const lines = [`(${world.x.toFixed(2)}, ${world.y.toFixed(2)}, ${world.z.toFixed(2)})`,
                   `class: ${row.class ?? 'none'}`, `observations: ${row.count}`];
    if (state.scores && state.scoreRange) {
      const scored = state.scores.get(layer.key);
      const v = scored ? scored.values[layer.indices[hit.index]] : NONE;
      const [lo, hi] = state.scoreRange;
      lines.push(`score: ${v === NONE ? 'none' : (lo + ((hi - lo) * v) / 254).toFixed(3)}`);
    }
    picked.textContent = lines.join('\n');
    state.picked = { world: [world.x, world.y, world.z], row };
  });
  // For tests and scripts: the world point's pixel (CSS pixels from the top left).
  state.project = ([x, y, z]) => {
    const p = new THREE.Vector3(x, y, z).project(camera);
    return [((p.x + 1) / 2) * renderer.domElement.clientWidth, ((1 - p.y) / 2) * renderer.domElement.clientHeight];
  };
  if (info.live) followLiveMap({ state, lod, layers, addChunks, paint, render, showFacts, progress, fit: bounds.isEmpty() ? { camera, controls } : null });
  render();
  window.slamvdbServe = state;
}

// Live mode: GET /api/events, each change applied in order (docs/serve-design.md "Live mode").
function followLiveMap({ state, lod, layers, addChunks, paint, render, showFacts, progress, fit }) {
  // events: changes applied; pending: received, not yet applied; opened: what was drawn before
  // following the map (`map --serve-wait-viewer` holds mapping until then).
  const live = { events: 0, pending: 0, submaps: [...new Set(layers.map((l) => l.chunk.submap))], progress: null, errors: [], skipped: 0 };
  live.opened = { submaps: [...live.submaps], points: state.points };
  state.live = live;
  const outOfMemory = new Set();  // unloaded submaps: their chunks stay as drawn (live_changes.js)
  const removeLayers = (drop) => {
    for (let i = layers.length - 1; i >= 0; --i) {
      if (!drop(layers[i].chunk)) continue;
      layers[i].points.removeFromParent();
      layers[i].points.geometry.dispose();
      layers.splice(i, 1);
    }
  };
  // The chunks a fetch of submap `id` replaces: its own and those of submaps merged into it.
  const removeSubmap = (id) => removeLayers((chunk) => replacedBy(chunk, id));
  // New anchors of submaps in memory or out of it (live_changes.js).
  const place = (moved) => {
    const placed = new Set(applyMoves(layers.map((l) => l.chunk), moved, rowsToT));
    for (const layer of layers) {
      if (!placed.has(layer.chunk)) continue;
      chunkMatrix(layer.chunk).decompose(layer.points.position, layer.points.quaternion, layer.points.scale);
      layer.points.updateMatrixWorld(true);
    }
  };
  // A submap's chunks anew (it is new, grew, or took a merged one): the old ones go when the new
  // ones are here. None (it left memory or was merged away since the event): left as drawn, the
  // next event says what became of it. 503 while the map is saved at the end of mapping, or no
  // answer (the server stopped): tried again for a few seconds (with --serve-linger the saved map
  // then answers), else left as drawn and counted.
  const refetch = async (params, remove) => {
    let answer;
    for (let attempt = 0; !answer; ++attempt) {
      try {
        answer = await fetchPoints({ lod, ...params });
      } catch (error) {
        if (error.status !== undefined && error.status !== 503) throw error;  // none: the server is gone
        if (attempt >= 5) { live.skipped += 1; return; }
        await new Promise((resolve) => setTimeout(resolve, 500));
      }
    }
    if (params.submap !== undefined && answer.chunks.length === 0) return;
    remove();
    const before = layers.length;
    const bounds = addChunks(answer.chunks);
    paint(state.scores, layers.slice(before));
    if (fit && !bounds.isEmpty()) {  // the map was empty when the page opened: look at the first points
      const centre = bounds.getCenter(new THREE.Vector3());
      const radius = Math.max(bounds.getSize(new THREE.Vector3()).length() / 2, 1) * 4;
      fit.camera.position.set(centre.x - 0.2 * radius, centre.y - 0.9 * radius, centre.z + 1.6 * radius);
      fit.camera.near = radius / 1000;
      fit.camera.far = radius * 20;
      fit.camera.updateProjectionMatrix();
      fit.controls.target.copy(centre);
      fit.controls.update();
      fit = null;
    }
  };
  const apply = async (change) => {
    if (change.resync) {  // the stream fell behind: everything anew, but what is out of memory
      const dropped = new Set(chunksDroppedOnResync(layers.map((l) => l.chunk), change, outOfMemory));
      place(change.moved);  // the anchors of those kept
      await refetch({}, () => removeLayers((chunk) => dropped.has(chunk)));
    } else {
      place(change.moved);
      // merged: its chunks are held by the target until the target's are fetched (drawn once);
      // unloaded: still in the map file, only out of memory: what was drawn of it is kept.
      applyMerges(layers.map((l) => l.chunk), change.merged);
      trackMemory(outOfMemory, change);
      for (const id of submapsToFetch(change, outOfMemory)) await refetch({ submap: id }, () => removeSubmap(id));
    }
    live.events += 1;
    live.submaps = [...new Set(layers.map((l) => l.chunk.heldBy ?? l.chunk.submap))];  // whose chunks are drawn
    state.points = layers.reduce((n, l) => n + l.indices.length, 0);
    showFacts(state.points);
    render();
  };
  let queue = Promise.resolve();
  const events = new EventSource('/api/events');
  events.addEventListener('submaps', (event) => {
    const change = JSON.parse(event.data);
    live.pending += 1;
    queue = queue.then(() => apply(change)).catch((error) => { live.errors.push(String(error)); })
      .finally(() => { live.pending -= 1; });
  });
  events.addEventListener('progress', (event) => {
    const p = JSON.parse(event.data);
    live.progress = p;
    progress.textContent = p.mapping ? `mapping: ${p.scans_done} of ${p.scans_total || '?'} scans` : `mapping done (${p.scans_done} scans)`;
  });
}

main().catch((error) => {
  document.getElementById('slamvdb-panel').textContent = `slamvdb: ${error.message}`;
  window.slamvdbServe = { ready: false, error: String(error) };
});
