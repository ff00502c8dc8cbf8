// The interactive 3D view inside a `slamvdb export --html` page. esbuild bundles this file with
// three.js into one script at build time, and the C++ writer (src/slamvdb/io/html_viewer.cpp)
// inlines that script and the points into the page: the page needs no network when viewed.
//
// Data in the page: <script id="slamvdb-meta" type="application/json"> (title, legend, colour bar,
// origin, point count) and <script id="slamvdb-points" type="application/octet-stream">: base64
// of N x 3 float32 positions (metres, world frame minus `origin`) followed by N x 3 uint8 colours.
import * as THREE from 'three';
import { orbitView } from './orbit_view.js';

function decodeBase64(text) {
  const binary = atob(text.trim());
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; ++i) bytes[i] = binary.charCodeAt(i);
  return bytes;
}

function cssColour([r, g, b]) {
  return `rgb(${r}, ${g}, ${b})`;
}

function addOverlay(meta) {
  const panel = document.getElementById('slamvdb-panel');
  const title = document.createElement('div');
  title.className = 'title';
  title.textContent = meta.title;
  panel.appendChild(title);
  const facts = document.createElement('div');
  facts.textContent = `${meta.count.toLocaleString()} voxels, ${meta.voxel_size} m; drag to orbit, right-drag to pan, wheel to zoom`;
  panel.appendChild(facts);
  for (const entry of meta.legend || []) {
    const row = document.createElement('div');
    row.className = 'legend';
    const swatch = document.createElement('span');
    swatch.className = 'swatch';
    swatch.style.background = cssColour(entry.color);
    row.appendChild(swatch);
    row.appendChild(document.createTextNode(entry.name));
    panel.appendChild(row);
  }
  if (meta.colour_bar) {
    const bar = meta.colour_bar;
    const row = document.createElement('div');
    row.className = 'colour-bar';
    row.style.background = `linear-gradient(to right, ${bar.stops.map(cssColour).join(', ')})`;
    panel.appendChild(row);
    const labels = document.createElement('div');
    labels.className = 'colour-bar-labels';
    labels.innerHTML = '<span></span><span></span><span></span>';
    labels.children[0].textContent = bar.min.toFixed(2);
    labels.children[1].textContent = bar.label;
    labels.children[2].textContent = bar.max.toFixed(2);
    panel.appendChild(labels);
  }
}

function main() {
  const meta = JSON.parse(document.getElementById('slamvdb-meta').textContent);
  const bytes = decodeBase64(document.getElementById('slamvdb-points').textContent);
  const n = meta.count;
  if (bytes.length !== n * 15) throw new Error(`point data holds ${bytes.length} bytes, expected ${n * 15}`);
  const positions = new Float32Array(bytes.buffer, 0, n * 3);
  const colours = new Uint8Array(bytes.buffer, n * 12, n * 3);

  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
  geometry.setAttribute('color', new THREE.BufferAttribute(colours, 3, true));
  geometry.computeBoundingSphere();
  // With attenuation a point of size s spans s * (viewport height / 2) / depth pixels, a voxel
  // v * (viewport height / 2) / (depth * tan(fov / 2)): size v / tan(25 deg) closes the gaps.
  const material = new THREE.PointsMaterial({ size: meta.voxel_size / Math.tan((25 * Math.PI) / 180), vertexColors: true, sizeAttenuation: true });
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x101418);
  scene.add(new THREE.Points(geometry, material));
  const sphere = geometry.boundingSphere;
  const radius = Math.max(sphere.radius, 1);
  scene.add(new THREE.AxesHelper(Math.min(radius * 0.2, 10)));  // x red, y green, z blue, at the origin

  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(window.innerWidth, window.innerHeight);
  document.body.appendChild(renderer.domElement);

  const c = sphere.center;
  const { render } = orbitView(renderer, scene, c, new THREE.Vector3(c.x - radius, c.y - radius, c.z + radius), radius);
  addOverlay(meta);
  render();
  // For tests and scripts: what was drawn.
  window.slamvdbViewer = { ready: true, points: n, canvas: renderer.domElement };
}

try {
  main();
} catch (error) {
  document.getElementById('slamvdb-panel').textContent = `slamvdb viewer: ${error.message}`;
  window.slamvdbViewer = { ready: false, error: String(error) };
}
