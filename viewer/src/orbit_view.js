// The camera both pages use (viewer.js of `export --html`, serve_page.js of `slamvdb serve`): a
// perspective camera with the map's z up, orbiting `target` from `eye`, redrawn on every orbit step
// and on a window resize. Returns { camera, controls, render }.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

export function orbitView(renderer, scene, target, eye, radius) {
  const camera = new THREE.PerspectiveCamera(50, window.innerWidth / window.innerHeight, radius / 1000, radius * 20);
  camera.up.set(0, 0, 1);  // the map's z is up
  camera.position.copy(eye);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(target);
  controls.update();
  const render = () => renderer.render(scene, camera);
  controls.addEventListener('change', render);
  window.addEventListener('resize', () => {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
    render();
  });
  return { camera, controls, render };
}
