// The three.js view: renderer, z-up scene and camera, orbit and move gizmo, the groups the
// page draws into, labels, standard views, the floor grid and the axis triad.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { TransformControls } from 'three/addons/controls/TransformControls.js';
import { CSS2DRenderer, CSS2DObject } from 'three/addons/renderers/CSS2DRenderer.js';
import { $, esc } from './util.js';

export const container = $('view');
export const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.xr.enabled = true;
container.appendChild(renderer.domElement);
export const labels = new CSS2DRenderer();
labels.domElement.style.position = 'absolute';
labels.domElement.style.top = '0';
labels.domElement.style.pointerEvents = 'none';
container.appendChild(labels.domElement);

export const scene = new THREE.Scene();
scene.background = new THREE.Color(0xe9edf1);
// The scene's frame is z up, and so is the view: the camera's up is +z, so that the
// orbit, the move gizmo's axes (red x, green y, blue z) and the triad are the scene's.
// Only in VR, whose frame is y up, does the world group turn (see sessionstart).
const hemisphere = new THREE.HemisphereLight(0xffffff, 0x667788, 2.0);
hemisphere.position.set(0, 0, 1);
scene.add(hemisphere);
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(2, -3, 4);
scene.add(sun);
export const world = new THREE.Group();
scene.add(world);

export const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 100);
camera.up.set(0, 0, 1);
export const orbit = new OrbitControls(camera, renderer.domElement);
orbit.enableDamping = false;
export const gizmo = new TransformControls(camera, renderer.domElement);
gizmo.setSize(0.8);
scene.add(gizmo.getHelper());
gizmo.addEventListener('dragging-changed', (e) => { orbit.enabled = !e.value; });

export function resize() {
  const w = container.clientWidth, h = container.clientHeight;
  renderer.setSize(w, h);
  labels.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);

export const obstacleGroup = new THREE.Group(); world.add(obstacleGroup);
export const envelopeGroup = new THREE.Group(); envelopeGroup.name = 'envelopes'; world.add(envelopeGroup);
export const gripGroup = new THREE.Group(); world.add(gripGroup);
export const arrowGroup = new THREE.Group(); world.add(arrowGroup);
export const contactGroup = new THREE.Group(); world.add(contactGroup);
// The task: the ports with their axes, the [path] the hand follows, the obstacles' names.
export const taskGroup = new THREE.Group(); taskGroup.name = 'task'; world.add(taskGroup);
export const PORT = 0x00838f;

// The hands' envelopes and the worker the verdict judged (pliant.assembly.access, posture).
export const bodyGroup = new THREE.Group();
bodyGroup.name = 'bodies';
world.add(bodyGroup);
export const branchGroup = new THREE.Group();
branchGroup.name = 'branches';
world.add(branchGroup);

export const OBSTACLE = 0x9aa3ad, TOO_CLOSE = 0xf9a825, INSIDE = 0xd32f2f;  // obstacle tints
// The hand's force and moment: magenta and purple, apart from the gizmo's red, green
// and blue axes and from the tube's colour map.
export const FORCE = 0xc2185b, MOMENT = 0x5e35b1;
export const tubeMaterial = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.5 });

export function label(at, text, kind) {
  const div = document.createElement('div');
  div.className = `label ${kind}`;
  div.innerHTML = `<span>${esc(text)}</span>`;
  const object = new CSS2DObject(div);
  object.position.copy(at);
  return object;
}
// What the view frames (set by frameOn): its centre, size and box, the standard view
// shown and the floor grid's cell [m].
export const view = { centre: null, size: 1, box: null, name: null, gridCell: null };
export function frameOn(box) {
  view.centre = box.getCenter(new THREE.Vector3());
  view.size = box.getSize(new THREE.Vector3()).length() || 1;
  view.box = box;
  drawFloor(box);
  setView('iso');
}

// Standard views, as CAD viewers have them: from a corner (iso), from above (top), from
// the front (looking along +y) and from the right (looking along -x); the scene's z up.
const VIEWS = {
  iso: [0.9, -1.1, 0.6], top: [0, -1e-3, 1.4], front: [0, -1.4, 0], right: [1.4, 0, 0],
};
export function setView(name) {
  if (!view.centre) return;
  const { centre, size } = view;
  orbit.target.copy(world.localToWorld(centre.clone()));
  camera.position.copy(orbit.target).add(new THREE.Vector3(...VIEWS[name]).multiplyScalar(size));
  camera.near = size / 200; camera.far = size * 50;
  camera.updateProjectionMatrix();
  orbit.update();
  view.name = name;
}
for (const name of Object.keys(VIEWS)) $(`view-${name}`).onclick = () => setView(name);

// A floor grid under the scene (its cell a round length, said in the panel) and a
// triad of the scene's axes in the corner: distances can be judged by eye.
let floor = null;
export function drawFloor(box) {
  if (floor) { world.remove(floor); floor.geometry.dispose(); floor.material.dispose(); }
  const size = box.getSize(new THREE.Vector3());
  const span = 1.4 * Math.max(size.x, size.y, 0.1);
  const raw = span / 16, decade = 10 ** Math.floor(Math.log10(raw));
  const cell = [1, 2, 5, 10].map((k) => k * decade).find((c) => c >= raw);
  const cells = 2 * Math.ceil(span / cell / 2);
  floor = new THREE.GridHelper(cells * cell, cells, 0x8a949e, 0xc3cad1);
  floor.name = 'floor';
  floor.rotation.x = Math.PI / 2;  // three's grid lies in x-z; the floor in x-y
  const c = box.getCenter(new THREE.Vector3());
  floor.position.set(Math.round(c.x / cell) * cell, Math.round(c.y / cell) * cell, box.min.z);
  world.add(floor);
  view.gridCell = cell;
  $('grid-cell').textContent = `grid ${cell >= 1 ? `${cell} m` : `${+(cell * 1e3).toPrecision(3)} mm`}`;
}
const triad = new THREE.Scene();
const triadCamera = new THREE.PerspectiveCamera(40, 1, 0.1, 10);
triadCamera.up.set(0, 0, 1);
for (const [axis, colour, text] of [[[1, 0, 0], 0xd32f2f, 'x'], [[0, 1, 0], 0x388e3c, 'y'], [[0, 0, 1], 0x1565c0, 'z']]) {
  const dir = new THREE.Vector3(...axis);
  triad.add(new THREE.ArrowHelper(dir, new THREE.Vector3(), 1, colour, 0.3, 0.15));
  const canvas = document.createElement('canvas');
  canvas.width = canvas.height = 64;
  const g = canvas.getContext('2d');
  g.fillStyle = `#${colour.toString(16).padStart(6, '0')}`;
  g.font = 'bold 48px system-ui, sans-serif';
  g.textAlign = 'center'; g.textBaseline = 'middle';
  g.fillText(text, 32, 34);
  const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: new THREE.CanvasTexture(canvas) }));
  sprite.position.copy(dir.multiplyScalar(1.35));
  sprite.scale.setScalar(0.5);
  triad.add(sprite);
}
const TRIAD = 96;  // px, in the view's lower left corner
export function drawTriad() {
  if (renderer.xr.isPresenting) return;
  triadCamera.position.copy(camera.position).sub(orbit.target).setLength(4.2);
  triadCamera.lookAt(0, 0, 0);
  const h = container.clientHeight;
  renderer.autoClear = false;
  renderer.clearDepth();
  renderer.setScissorTest(true);
  renderer.setScissor(8, 8, TRIAD, TRIAD);
  renderer.setViewport(8, 8, TRIAD, TRIAD);
  renderer.render(triad, triadCamera);
  renderer.setScissorTest(false);
  renderer.setViewport(0, 0, container.clientWidth, h);
  renderer.autoClear = true;
}

