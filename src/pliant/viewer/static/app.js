// pliant's browser environment: the scene, the part as a tube, grips dragged with the mouse
// (TransformControls) or VR controllers (WebXR), the real-time frame at display rate and
// accurate results as they arrive. Scene units are metres, z up. The page is ES modules:
// this one (the session: state, messages, scene, grips, frames, accurate answers), view.js
// (three.js, views, floor, triad), equilibria.js (other shapes), xr.js (VR), util.js, and
// protocol.js, made from pliant/viewer/protocol.py, through which every message is sent.
import * as THREE from 'three';
import { message } from './protocol.js';
import { $, esc, fixed, fmt, interp, slug } from './util.js';
import {
  FORCE, INSIDE, MOMENT, OBSTACLE, PORT, TOO_CLOSE, arrowGroup, bodyGroup, branchGroup, camera,
  contactGroup, drawTriad, envelopeGroup, frameOn, gizmo, gripGroup, label, labels,
  obstacleGroup, renderer, resize, scene, setView, taskGroup, tubeMaterial, world,
} from './view.js';
import { setupEquilibria } from './equilibria.js';
import { setupXR } from './xr.js';

const params = new URLSearchParams(location.search);

// A WebXR emulator (iwer) where the page is asked to (?xr=emulate): tests, and desktops
// without a headset.
let xrDevice = null;
if (params.get('xr') === 'emulate') {
  const { XRDevice, metaQuest3 } = await import('iwer');
  xrDevice = new XRDevice(metaQuest3);
  xrDevice.installRuntime({ forceInstall: true });  // over the browser's own (headless) one
}

// -- state --------------------------------------------------------------------------------------
const state = {
  scene: null, frame: null, accurate: null, grips: new Map(), frames: 0, accurates: 0,
  errors: [], seq: 0, inFlight: false, queued: null, saved: null, sentAt: new Map(),
  latency: [], haptics: [], equilibria: null,
};
let tube = null, ghost = null;

// -- the websocket ------------------------------------------------------------------------------
const ws = new WebSocket(`ws://${location.host}/ws`);
const send = ({ type, ...fields }) => ws.send(message(type, fields));
const { onEquilibria, staleEquilibria } = setupEquilibria(state, send);
ws.onopen = () => {
  loading('opening the scene: reading its meshes and starting the solver…');
  send({ type: 'hello' });
};
ws.onclose = () => { $('status').textContent = 'disconnected from the server'; loading('disconnected from the server'); };
// What the view waits for, over it, until the part is there.
function loading(text) {
  const el = $('loading');
  el.hidden = !text;
  el.textContent = text || '';
}
ws.onmessage = (event) => {
  const msg = JSON.parse(event.data);
  if (msg.type === 'scene') { onScene(msg); loading('solving the start pose…'); }
  else if (msg.type === 'frame') onFrame(msg);
  else if (msg.type === 'accurate') onAccurate(msg);
  else if (msg.type === 'equilibria') onEquilibria(msg);
  else if (msg.type === 'saved') { state.saved = msg.name; note(`saved ${msg.name} in ${msg.folder}`); }
  else if (msg.type === 'error') {
    state.errors.push(msg);
    $('find').disabled = false;
    note(`error${msg.field ? ` (${msg.field})` : ''}: ${msg.message}`, true);
    if (!state.scene) loading(msg.message);
    state.inFlight = false;
  }
};
function note(text, bad = false) {
  const el = $('message');
  el.textContent = text;
  el.style.color = bad ? '#b00' : '';
}

// -- the scene ----------------------------------------------------------------------------------
function onScene(msg) {
  staleEquilibria();  // a grip switched mode or a session loaded: another pose
  const first = state.scene === null || state.scene.file !== msg.file;
  state.scene = msg;
  $('scene-name').textContent = msg.name;
  if (first) {
    obstacleGroup.clear();
    const material = new THREE.MeshStandardMaterial({
      color: OBSTACLE, roughness: 0.8, metalness: 0.1, transparent: true, opacity: 0.85,
    });
    for (const ob of msg.obstacles) {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.Float32BufferAttribute(ob.vertices.flat(), 3));
      geometry.setIndex(ob.faces.flat());
      geometry.computeVertexNormals();
      const mesh = new THREE.Mesh(geometry, material.clone());
      mesh.name = ob.name;
      obstacleGroup.add(mesh);
    }
    drawEnvelopes(msg.envelopes || []);
    drawTask(msg);
    frameCamera();
  }
  buildGrips(msg.grips);
  $('path-row').hidden = !msg.path;
  $('path-step').textContent = msg.path ? `${msg.path.positions.length} steps` : '';
}

// -- playing a scene's [path] ----------------------------------------------------------------
// The grip is carried through the path's poses one at a time: the next pose is sent when
// the server has answered the last with its accurate equilibrium (or said it has none):
// every step shown is solved, each from the one before, as `pliant evaluate` follows the
// path; at most every 30 ms so that it can be watched.
const player = { playing: false, k: 0, timer: null, waiting: null };
$('play').onclick = () => (player.playing ? stopPath() : playPath());
function playPath() {
  const path = state.scene && state.scene.path;
  const handle = path && state.grips.get(path.grip);
  if (!handle) return;
  player.playing = true;
  player.k = 0;
  player.waiting = null;
  $('play').textContent = 'Stop';
  gizmo.attach(handle);
  playStep();
}
function stopPath(done = false) {
  player.playing = false;
  clearTimeout(player.timer);
  $('play').textContent = 'Play path';
  const n = state.scene && state.scene.path ? state.scene.path.positions.length : 0;
  $('path-step').textContent = done ? `played ${n} steps, each solved accurately` : `stopped at step ${player.k} of ${n}`;
}
function answered(index) {
  // The accurate answer (or its failure) of the pose of event ``index``, or a later one.
  return (state.accurate && state.accurate.index >= index) || (state.failed && state.failed.index >= index);
}
function playStep() {
  if (!player.playing) return;
  if (state.inFlight) { player.timer = setTimeout(playStep, 10); return; }
  if (player.waiting === null && player.k > 0 && state.frame) player.waiting = state.frame.index;
  if (player.waiting !== null && !answered(player.waiting)) { player.timer = setTimeout(playStep, 10); return; }
  player.waiting = null;
  const path = state.scene.path;
  if (player.k >= path.positions.length) { stopPath(true); return; }
  const handle = state.grips.get(path.grip);
  const k = player.k;
  handle.position.set(...path.positions[k]);
  if (path.tangents) handle.quaternion.setFromUnitVectors(Z, new THREE.Vector3(...path.tangents[k]).normalize());
  moved(handle);
  player.k = k + 1;
  $('path-step').textContent = `step ${player.k} of ${path.positions.length}`;
  player.timer = setTimeout(playStep, 30);
}

// A variation study's tolerance envelope (pliant view --envelope): what the part sweeps
// over every sample, along the path (grey) and at the final pose (orange), see-through.
function drawEnvelopes(envelopes) {
  envelopeGroup.clear();
  for (const en of envelopes) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.Float32BufferAttribute(en.vertices.flat(), 3));
    geometry.setIndex(en.faces.flat());
    geometry.computeVertexNormals();
    const final = en.name.includes('final');
    const material = new THREE.MeshStandardMaterial({
      color: final ? 0xe0701e : 0x9aa3ad, transparent: true, opacity: final ? 0.45 : 0.18,
      depthWrite: false, side: THREE.DoubleSide,
    });
    const mesh = new THREE.Mesh(geometry, material);
    mesh.name = en.name;
    envelopeGroup.add(mesh);
  }
  $('envelope-row').hidden = envelopes.length === 0;
}

// Ports as a ring with the axis the part leaves along, the path as a dashed line through
// the hand's poses, and each obstacle's name over it (grey; the clearance table's row
// lights its obstacle up).
function drawTask(msg) {
  for (const child of [...taskGroup.children]) child.traverse((o) => { if (o.isCSS2DObject) o.element.remove(); });
  taskGroup.clear();
  const r = msg.part.radius, L = msg.part.length;
  for (const port of msg.ports || []) {
    const at = new THREE.Vector3(...port.position), axis = new THREE.Vector3(...port.axis).normalize();
    const group = new THREE.Group();
    group.name = `port ${port.name}`;
    const ring = new THREE.Mesh(new THREE.TorusGeometry(2.2 * r, 0.35 * r, 8, 32),
      new THREE.MeshBasicMaterial({ color: PORT }));
    ring.position.copy(at);
    ring.quaternion.setFromUnitVectors(Z, axis);
    group.add(ring);
    group.add(new THREE.ArrowHelper(axis, at, 0.12 * L, PORT, 0.03 * L, 0.015 * L));
    group.add(label(at.clone().addScaledVector(axis, 0.13 * L), `port: ${port.name}`, 'port'));
    taskGroup.add(group);
  }
  if (msg.path && msg.path.positions.length > 1) {
    const points = msg.path.positions.map((p) => new THREE.Vector3(...p));
    const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(points),
      new THREE.LineDashedMaterial({ color: 0x2d6cdf, dashSize: 0.02 * L, gapSize: 0.012 * L }));
    line.computeLineDistances();
    line.name = 'path';
    taskGroup.add(line);
  }
  for (const mesh of obstacleGroup.children) {
    const box = new THREE.Box3().setFromObject(mesh);
    const top = box.getCenter(new THREE.Vector3());
    top.z = box.max.z;
    taskGroup.add(label(top, mesh.name, 'obstacle'));
  }
}
function highlight(name) {
  for (const mesh of obstacleGroup.children) mesh.material.emissive.set(mesh.name === name ? 0x335577 : 0x000000);
  state.highlighted = name;
}

function frameCamera() {
  const box = new THREE.Box3();
  for (const g of state.scene.grips) box.expandByPoint(new THREE.Vector3(...g.position));
  obstacleGroup.updateMatrixWorld(true);
  box.expandByObject(obstacleGroup);
  if (box.isEmpty()) box.expandByPoint(new THREE.Vector3(state.scene.part.length, 0, 0));
  frameOn(box);
}

const Z = new THREE.Vector3(0, 0, 1);
function buildGrips(grips) {
  gizmo.detach();
  gripGroup.clear();
  state.grips.clear();
  const r = state.scene.part.radius;
  const panel = $('grips');
  panel.innerHTML = '';
  for (const g of grips) {
    const movable = g.mode === 'position';
    const handle = new THREE.Mesh(
      movable ? new THREE.SphereGeometry(Math.max(1.6 * r, 0.004), 20, 12)
              : new THREE.BoxGeometry(2.4 * r, 2.4 * r, 2.4 * r),
      new THREE.MeshStandardMaterial({
        color: movable ? 0x2d6cdf : (g.mode === 'force' ? FORCE : 0x555555),
        transparent: movable, opacity: movable ? 0.55 : 1,
      }));
    handle.position.set(...g.position);
    if (g.tangent) handle.quaternion.setFromUnitVectors(Z, new THREE.Vector3(...g.tangent).normalize());
    handle.userData = { grip: g, movable, holdsTangent: !!g.tangent };
    handle.name = g.name;
    gripGroup.add(handle);
    state.grips.set(g.name, handle);
    if (g.mode !== 'fixed') panel.appendChild(gripPanel(g));
  }
  const first = [...state.grips.values()].find((h) => h.userData.movable);
  if (first) gizmo.attach(first);
}

function gripPanel(g) {
  const div = document.createElement('div');
  div.className = 'grip';
  div.id = `grip-${slug(g.name)}`;
  div.innerHTML = `<div class="row"><span class="name">${esc(g.name)}</span>
    <select class="mode" aria-label="how ${esc(g.name)} is driven">
      <option value="position"${g.mode === 'position' ? ' selected' : ''}>held by position</option>
      <option value="force"${g.mode === 'force' ? ' selected' : ''}>pushed by a force</option>
    </select></div>
    <div class="numbers pose"></div>
    <div class="numbers force-value" data-newton=""></div>
    <div class="numbers moment-value" data-newton-metre=""></div>`;
  if (g.mode === 'force') {
    const f = g.force || [0, 0, 0];
    const row = document.createElement('div');
    row.className = 'row';
    row.innerHTML = 'F [N] ' + [0, 1, 2].map((i) =>
      `<input class="f" data-i="${i}" type="number" step="0.1" value="${f[i].toFixed(3)}">`).join('') +
      '<button class="apply">Apply</button>';
    div.appendChild(row);
    row.querySelector('.apply').onclick = () => {
      const force = [...row.querySelectorAll('input.f')].map((el) => Number(el.value));
      send({ type: 'mode', grip: g.name, mode: 'force', force, moment: g.moment });
    };
  }
  div.querySelector('.mode').onchange = (e) => send({ type: 'mode', grip: g.name, mode: e.target.value });
  div.querySelector('.pose').textContent = `at (${g.position.map((x) => fixed(x, 3)).join(', ')}) m`;
  return div;
}

// -- dragging -----------------------------------------------------------------------------------
gizmo.addEventListener('objectChange', () => moved(gizmo.object));
function moved(handle) {
  staleEquilibria();
  const g = handle.userData.grip;
  const tangent = handle.userData.holdsTangent ? Z.clone().applyQuaternion(handle.quaternion).toArray() : null;
  const pose = { grip: g.name, position: handle.position.toArray(), tangent };
  g.position = pose.position;
  const el = document.querySelector(`#grip-${slug(g.name)} .pose`);
  if (el) el.textContent = `at (${pose.position.map((x) => fixed(x, 3)).join(', ')}) m`;
  // The latest pose of each grip waits its turn (two hands in VR move two grips at once:
  // each is sent in turn, none starved); null when none waits.
  if (!state.queued) state.queued = new Map();
  state.queued.delete(g.name);
  state.queued.set(g.name, pose);
  flush();
}
function flush() {  // one move in flight: the server always works on the latest poses
  if (state.inFlight || !state.queued || ws.readyState !== 1) return;
  const [name, pose] = state.queued.entries().next().value;
  state.queued.delete(name);
  if (state.queued.size === 0) state.queued = null;
  state.inFlight = true;
  state.lastPose = pose;
  state.seq += 1;
  state.sentAt.set(state.seq, performance.now());
  send({ type: 'move', seq: state.seq, ...pose });
}
$('translate').onclick = () => setGizmoMode('translate');
$('rotate').onclick = () => setGizmoMode('rotate');
function setGizmoMode(mode) {
  gizmo.setMode(mode);
  $('translate').classList.toggle('on', mode === 'translate');
  $('rotate').classList.toggle('on', mode === 'rotate');
}
window.addEventListener('keydown', (e) => {
  if (e.target.tagName === 'INPUT') return;
  if (e.key === 't') setGizmoMode('translate');
  if (e.key === 'r') setGizmoMode('rotate');
});
renderer.domElement.addEventListener('dblclick', (e) => {  // pick which grip the gizmo holds
  const hit = pick(e);
  if (hit && hit.userData.movable) gizmo.attach(hit);
});
function pick(e) {
  const rect = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1,
    -((e.clientY - rect.top) / rect.height) * 2 + 1);
  const ray = new THREE.Raycaster();
  ray.setFromCamera(ndc, camera);
  return ray.intersectObjects(gripGroup.children, false)[0]?.object ?? null;
}
$('solve').onclick = () => send({ type: 'solve' });
$('save').onclick = () => send({ type: 'save', name: $('session-name').value });
$('load').onclick = () => send({ type: 'load', name: $('session-name').value });
$('colour').onchange = () => { if (state.frame) drawTube(state.frame); };

// -- frames (real-time) -------------------------------------------------------------------------
function onFrame(msg) {
  state.frame = msg;
  state.frames += 1;
  if (msg.seq && msg.seq === state.seq) {
    state.inFlight = false;
    const t0 = state.sentAt.get(msg.seq);
    if (t0 !== undefined) { state.latency.push(performance.now() - t0); state.sentAt.delete(msg.seq); }
    flush();
  }
  drawTube(msg);
  loading(null);
  const contacts = msg.contacts.map((p) => ({ point: p }));
  drawContacts(contacts.concat(state.accurate?.ok ? state.accurate.contacts : []));
  // One clearance: the accurate model's while the preview has not drifted from it (it is
  // the verdict's, rounded to what it resolves), else the preview's, labelled so.
  if (state.accurate?.ok && msg.drift < FRESH_DRIFT) showClearance(state.accurate.interference, 'accurate');
  else showClearance(msg.interference, 'real-time preview');
  showWarnings();
  showFreshness();
  $('frame-details').textContent = `real-time frame ${msg.index}: ${(msg.seconds * 1e3).toFixed(1)} ms` +
    `${msg.converged ? '' : ' (not converged)'}; the shape has drifted ${(msg.drift * 100).toFixed(1)} % ` +
    'of the length from the last accurate one';
}

// Plain words on top, how current the forces are: up to date, being solved, or from an
// earlier pose (the numbers then greyed), or failed here (the last good answer kept).
function showFreshness() {
  const frame = state.frame, acc = state.accurate;
  let text, cls;
  if (state.failed && (!acc || state.failed.index > acc.index)) {
    text = 'no equilibrium at this pose: the forces shown are from the last pose that had one';
    cls = 'failed';
  } else if (!acc) {
    text = 'the accurate model is solving the start pose…'; cls = 'stale';
  } else if (frame && frame.pending) {
    text = 'the accurate model is solving this pose…'; cls = 'stale';
  } else if (frame && frame.index > acc.index && frame.drift > 0) {
    text = 'the pose has moved since the forces were computed (Solve accurate to update)'; cls = 'stale';
  } else {
    text = 'forces and verdict are for this pose'; cls = 'fresh';
  }
  $('status').textContent = text;
  $('status').className = `status ${cls}`;
  document.body.dataset.results = cls;
}

function drawTube(frame) {
  const points = frame.curve.map((p) => new THREE.Vector3(...p));
  const path = new THREE.CatmullRomCurve3(points, false, 'centripetal');
  const segments = Math.max(2 * points.length, 32), radial = 12;
  const geometry = new THREE.TubeGeometry(path, segments, state.scene.part.radius, radial, false);
  const values = colourValues(frame, segments);
  const colours = new Float32Array(geometry.attributes.position.count * 3);
  const c = new THREE.Color();
  for (let i = 0; i <= segments; i++) {
    colourOf(values.kind, values.v[i], values.max, c);
    for (let j = 0; j <= radial; j++) c.toArray(colours, 3 * (i * (radial + 1) + j));
  }
  geometry.setAttribute('color', new THREE.BufferAttribute(colours, 3));
  if (tube) { tube.geometry.dispose(); tube.geometry = geometry; }
  else { tube = new THREE.Mesh(geometry, tubeMaterial); tube.name = 'tube'; world.add(tube); }
  showColourBar(values);
}

// The colour map's scale: a bar from 0 to the largest value, with its unit, or the
// clearance's three colours with what each means.
function showColourBar(values) {
  const bar = $('colour-bar');
  if (values.kind === 'clearance') {
    bar.innerHTML = '<span class="swatch" style="background:#43a047"></span>clear ' +
      '<span class="swatch" style="background:#f9a825"></span>nearer than the margin ' +
      '<span class="swatch" style="background:#d32f2f"></span>inside';
  } else {
    const unit = values.kind === 'moment' ? 'N m' : '1/m';
    const what = values.kind === 'moment' ? 'bending moment (accurate)' : 'curvature (real-time)';
    const stops = [0, 0.25, 0.5, 0.75, 1].map((t) => `hsl(${(0.66 * (1 - t) * 360).toFixed(0)} 85% 50%)`);
    bar.innerHTML = `<div class="gradient" style="background:linear-gradient(to right, ${stops.join(', ')})"></div>` +
      `<div class="ticks"><span>0</span><span>${what}</span><span>${fmt(values.max)} ${unit}</span></div>`;
  }
  bar.dataset.max = values.max;
  bar.dataset.kind = values.kind;
}


function colourValues(frame, segments) {
  const kind = $('colour').value;
  const L = frame.s[frame.s.length - 1];
  const at = (s, xs, ys) => interp(s, xs, ys);
  const v = [];
  let max = 0;
  for (let i = 0; i <= segments; i++) {
    const s = (i / segments) * L;
    let value;
    if (kind === 'moment' && state.accurate?.ok) value = at(s, state.accurate.s, state.accurate.bending_moment);
    else if (kind === 'clearance') value = clearanceAt(frame.interference, s);
    else value = at(s, frame.s, frame.curvature);
    v.push(value);
    if (kind !== 'clearance') max = Math.max(max, value);
  }
  return { kind: kind === 'moment' && !state.accurate?.ok ? 'curvature' : kind, v, max };
}
function clearanceAt(report, s) {
  for (const span of report.penetrations) if (s >= span.s_start && s <= span.s_end) return 2;
  for (const span of report.too_close) if (s >= span.s_start && s <= span.s_end) return 1;
  return 0;
}
function colourOf(kind, value, max, c) {
  if (kind === 'clearance') return c.set(value === 2 ? 0xd32f2f : value === 1 ? 0xf9a825 : 0x43a047);
  const t = max > 0 ? Math.min(value / max, 1) : 0;
  return c.setHSL(0.66 * (1 - t), 0.85, 0.5);
}

// Contact markers: one geometry and one material for all, the meshes kept and reused
// frame after frame (made anew they would leak GPU buffers at display rate).
const contactMaterial = new THREE.MeshBasicMaterial({ color: 0xe65100 });
let contactGeometry = null;
function drawContacts(contacts) {
  const r = state.scene.part.radius;
  if (!contactGeometry || contactGeometry.parameters.radius !== 1.3 * r) {
    if (contactGeometry) contactGeometry.dispose();
    contactGeometry = new THREE.SphereGeometry(1.3 * r, 10, 8);
    for (const dot of contactGroup.children) dot.geometry = contactGeometry;
  }
  while (contactGroup.children.length < contacts.length) {
    contactGroup.add(new THREE.Mesh(contactGeometry, contactMaterial));
  }
  contactGroup.children.forEach((dot, i) => {
    dot.visible = i < contacts.length;
    if (dot.visible) dot.position.set(...contacts[i].point);
  });
}

// -- accurate results ----------------------------------------------------------------------------
function onAccurate(msg) {
  state.accurates += 1;
  if (!msg.ok) {
    note(`accurate solve failed: ${msg.error} (the last good shape stays)`, true);
    state.failed = msg;
    showWarnings();
    showFreshness();
    return;
  }
  state.accurate = msg;
  state.failed = null;
  pulseHands(msg);
  drawGhost(msg);
  drawFitted(msg.fitted || []);
  drawBranches(msg.branches || []);
  drawLoads(msg);
  showClearance(msg.interference, 'accurate');
  if (state.frame) drawTube(state.frame);
  const lines = [];
  if (msg.min_bend_radius !== null) lines.push(`tightest bend ${(msg.min_bend_radius * 1e3).toFixed(1)} mm, ${msg.min_bend_radius_s.toFixed(3)} m along the part` +
    (msg.allowed_bend_radius ? ` (its limit: ${(msg.allowed_bend_radius * 1e3).toFixed(0)} mm, centreline)` : ''));
  lines.push(msg.stable === false ? 'unstable: the part would snap into another shape'
    : msg.stable ? 'stable: it stays in this shape' : '');
  $('shape').innerHTML = lines.filter(Boolean).map((l) => `<div>${esc(l)}</div>`).join('');
  $('accurate-details').textContent = `accurate solve (event ${msg.index}): ${(msg.solve_seconds * 1e3).toFixed(0)} ms, ` +
    `${msg.iterations} Newton iterations, residual ${msg.residual?.toExponential(1)}` +
    (msg.smallest_eigenvalue !== null && msg.smallest_eigenvalue !== undefined
      ? `; smallest eigenvalue ${msg.smallest_eigenvalue.toExponential(2)} N m` : '');
  showVerdict(msg.verdict);
  drawBodies(msg.verdict);
  showWarnings();
  showFreshness();
  if (state.equilibria) onEquilibria(state.equilibria);  // which one is shown now
}

$('envelope').addEventListener('change', (e) => { envelopeGroup.visible = e.target.checked; });
$('bodies').addEventListener('change', (e) => { bodyGroup.visible = e.target.checked; });

// The hands and the worker the verdict judged, drawn as judged: each hand's ring round
// the part and its forearm out along the best approach (in its access zone's colour),
// the worker's stick figure (feet, hip, shoulder, elbow, grip) in its posture's.
const ZONE = { green: 0x1b7f3b, yellow: 0xb07d00, red: 0xc0262d, unchecked: 0x6b6b6b, info: 0x3d5a80 };
function drawBodies(verdict) {
  for (const child of [...bodyGroup.children]) { child.geometry?.dispose(); child.material?.dispose(); }
  bodyGroup.clear();
  if (!verdict) return;
  for (const h of verdict.hands) {
    const material = new THREE.MeshStandardMaterial({ color: ZONE[h.zone], transparent: true, opacity: 0.35 });
    const ring = new THREE.Mesh(new THREE.SphereGeometry(h.ring, 24, 16), material);
    ring.position.set(...h.centre);
    ring.name = `hand ${h.grip}`;
    const along = new THREE.Vector3(...h.approach);
    const arm = new THREE.Mesh(new THREE.CylinderGeometry(0.03, 0.045, h.reach, 20), material.clone());
    arm.position.copy(new THREE.Vector3(...h.centre).addScaledVector(along, h.reach / 2));
    arm.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), along);
    arm.name = `forearm ${h.grip}`;
    bodyGroup.add(ring, arm);
  }
  for (const w of verdict.worker) {
    const geometry = new THREE.BufferGeometry().setFromPoints(w.chain.map((p) => new THREE.Vector3(...p)));
    const line = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: ZONE[w.zone] }));
    line.name = `worker ${w.grip}`;
    bodyGroup.add(line);
  }
}

// The pose's A/D verdict, judged on the server by the same rules as `pliant evaluate`:
// the page only shows it.
function showVerdict(verdict) {
  const box = $('verdict');
  if (!verdict) {
    box.className = 'verdict muted';
    box.textContent = 'no verdict for this scene';
    $('verdict-items').innerHTML = '';
    return;
  }
  box.className = `verdict ${verdict.passes ? 'pass' : 'fail'} ${verdict.zone}`;
  box.textContent = verdict.headline;
  $('verdict-items').innerHTML = verdict.items.map((i) => `<li><span class="zone ${i.zone}">${esc(i.zone)}</span>` +
    `${esc(i.text)}<div class="source">${esc(i.source)}</div></li>`).join('');
}

// Another part's tube along its neutral line, as an accurate answer gives it.
function tubeAlong(position, radius, radial) {
  const points = position.map((p) => new THREE.Vector3(...p));
  const path = new THREE.CatmullRomCurve3(points, false, 'centripetal');
  return new THREE.TubeGeometry(path, Math.max(2 * points.length, 32), radius, radial, false);
}

// A flexible part already fitted is drawn as the accurate answer has it: deformed where
// the part touches it (its obstacle mesh, same name, takes the new tube).
function drawFitted(fitted) {
  for (const part of fitted) {
    const mesh = obstacleGroup.getObjectByName(part.name);
    if (!mesh || part.position.length < 2) continue;
    mesh.geometry.dispose();
    mesh.geometry = tubeAlong(part.position, part.radius, 16);
    mesh.userData.fitted = true;
  }
}

// A harness's branches, solved with the part: tubes of their own, redrawn with each
// accurate answer (the real-time frames do not carry them), all of one material.
const branchMaterial = new THREE.MeshStandardMaterial({ color: 0x3b6ea5, roughness: 0.6 });
function drawBranches(branches) {
  for (const child of [...branchGroup.children]) child.geometry.dispose();
  branchGroup.clear();
  for (const part of branches) {
    if (part.position.length < 2) continue;
    const mesh = new THREE.Mesh(tubeAlong(part.position, part.radius, 12), branchMaterial);
    mesh.name = part.name;
    branchGroup.add(mesh);
  }
}

function drawGhost(msg) {
  if (ghost) { ghost.geometry.dispose(); world.remove(ghost); }
  const geometry = new THREE.BufferGeometry().setFromPoints(msg.position.map((p) => new THREE.Vector3(...p)));
  ghost = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: 0x222222 }));
  ghost.name = 'accurate';
  world.add(ghost);
}

function drawLoads(msg) {
  for (const child of [...arrowGroup.children]) child.traverse((o) => { if (o.isCSS2DObject) o.element.remove(); });
  arrowGroup.clear();
  const L = state.scene.part.length;
  for (const load of msg.loads) {
    const handle = state.grips.get(load.name);
    if (!handle || handle.userData.grip.mode === 'fixed') continue;
    const F = new THREE.Vector3(...load.force), M = new THREE.Vector3(...load.moment);
    const at = new THREE.Vector3(...load.position);
    const f = F.length(), m = M.length();
    if (f > 0) arrow(at, F, 0.12 * L * (1 + Math.log10(1 + f)), FORCE, `F ${f.toFixed(2)} N`, 'force');
    if (m > 0) arrow(at, M, 0.08 * L * (1 + Math.log10(1 + 100 * m)), MOMENT, `M ${m.toFixed(3)} N m`, 'moment');
    const pushed = handle.userData.grip.mode === 'force';
    if (pushed) {  // a pushed grip goes where the push takes the part
      handle.position.copy(at);
      handle.userData.grip.position = load.position;
    }
    const box = document.querySelector(`#grip-${slug(load.name)}`);
    if (box) {
      const fe = box.querySelector('.force-value'), me = box.querySelector('.moment-value');
      fe.dataset.newton = f; me.dataset.newtonMetre = m;
      const what = pushed ? 'applied' : 'hand';
      fe.textContent = `${what} force ${f.toFixed(3)} N (${load.force.map((x) => fixed(x, 2)).join(', ')})`;
      me.textContent = `${what} moment ${m.toFixed(4)} N m (${load.moment.map((x) => fixed(x, 3)).join(', ')})`;
      box.querySelector('.pose').textContent = `at (${load.position.map((x) => fixed(x, 3)).join(', ')}) m`;
    }
  }
}
// A force is an arrow; a moment the engineering double-headed arrow along its axis
// (right-hand rule). Each label sits just past its own tip (the arrow's local +y), the
// force's above it and the moment's below, so that the two never cover each other.
const LABEL_PAST = 1.04;  // where an arrow's label sits, in arrow lengths from its base
function arrow(at, dir, length, colour, text, kind) {
  const head = 0.2 * length, width = 0.08 * length;
  const helper = new THREE.ArrowHelper(dir.clone().normalize(), at, length, colour, head, width);
  helper.name = kind;
  if (kind === 'moment') {
    const second = new THREE.Mesh(new THREE.ConeGeometry(0.5 * width, head, 12),
      new THREE.MeshBasicMaterial({ color: colour }));
    second.position.y = length - 1.6 * head;
    helper.add(second);
  }
  helper.add(label(new THREE.Vector3(0, LABEL_PAST * length, 0), text, kind));
  arrowGroup.add(helper);
}

const FRESH_DRIFT = 0.002;  // of the length: the accurate answer still stands for the pose
function showClearance(report, source) {
  $('clearance-source').textContent = source === 'accurate'
    ? 'the accurate model (as the verdict)' : 'the real-time preview (the accurate answer is on its way)';
  // Interference on the obstacles themselves, whatever the tube's colour map shows.
  const entered = new Set(report.penetrations.map((p) => p.obstacle));
  const near = new Set(report.too_close.map((p) => p.obstacle));
  for (const mesh of obstacleGroup.children) {
    mesh.material.color.set(entered.has(mesh.name) ? INSIDE : near.has(mesh.name) ? TOO_CLOSE : OBSTACLE);
  }
  const rows = report.clearances.map((c) => {
    const cls = c.clearance < -0.01 * state.scene.part.radius ? 'bad' : c.clearance < report.margin ? 'near' : '';
    const on = c.obstacle === state.highlighted ? ' on' : '';
    return `<tr class="${cls}${on}" data-obstacle="${esc(c.obstacle)}" title="show it in the view">` +
      `<td>${esc(c.obstacle)}</td><td class="num">${c.clearance === 0 ? '0 (touching)' : `${(c.clearance * 1e3).toFixed(1)} mm`}</td>` +
      `<td class="num">at s ${c.s.toFixed(3)} m</td></tr>`;
  });
  $('clearance').innerHTML = rows.length ? `<table>${rows.join('')}</table>` : '<span class="muted">no obstacles</span>';
  for (const row of $('clearance').querySelectorAll('tr')) {
    row.onclick = () => { const name = row.dataset.obstacle; highlight(state.highlighted === name ? null : name); };
  }
}

function showWarnings() {
  const out = [];
  const frame = state.frame, acc = state.accurate;
  if (state.failed) out.push(`no accurate equilibrium at this pose: ${state.failed.error}`);
  if (acc?.ok) out.push(...acc.warnings);
  if (frame) out.push(...frame.warnings);  // the server's words (assembly/checks.py), as the CLI's
  $('notes').innerHTML = (acc?.ok ? acc.notes : []).map((n) => `<li>${esc(n)}</li>`).join('');
  $('warnings').innerHTML = out.length ? out.map((w) => `<li>${esc(w)}</li>`).join('') : '<li class="muted">none</li>';
}

const { hands, pulseHands, followHands } = setupXR(state, moved);

// -- the loop -----------------------------------------------------------------------------------
renderer.setAnimationLoop(() => {
  followHands();
  renderer.render(scene, camera);
  drawTriad();
  labels.render(scene, camera);
  state.rendered = (state.rendered || 0) + 1;
});
resize();

// For tests and scripts: the page's state and where a grip is on the screen.
window.pliant = {
  state, xrDevice, world, camera, hands,
  gripScreen(name) {
    const handle = state.grips.get(name);
    const p = handle.getWorldPosition(new THREE.Vector3()).project(camera);
    const rect = renderer.domElement.getBoundingClientRect();
    return { x: rect.left + (p.x + 1) / 2 * rect.width, y: rect.top + (1 - p.y) / 2 * rect.height };
  },
  worldOf(point) { return world.localToWorld(new THREE.Vector3(...point)).toArray(); },
  setView,
  // Where an arrow's tip and its label are on the screen (px), and the label's box.
  arrowLabel(kind) {
    const helper = arrowGroup.getObjectByName(kind);
    if (!helper) return null;
    const label = helper.children.find((o) => o.isCSS2DObject);
    const rect = renderer.domElement.getBoundingClientRect();
    const screen = (v) => {
      const p = helper.localToWorld(v).project(camera);
      return { x: rect.left + (p.x + 1) / 2 * rect.width, y: rect.top + (1 - p.y) / 2 * rect.height };
    };
    const el = label.element;
    const box = el.getBoundingClientRect(), text = el.firstChild.getBoundingClientRect();
    return {
      tip: screen(new THREE.Vector3(0, label.position.y / LABEL_PAST, 0)),
      base: screen(new THREE.Vector3()),
      at: screen(label.position.clone()),
      anchor: { x: box.left + box.width / 2, y: box.top + box.height / 2 },
      text: { left: text.left, right: text.right, top: text.top, bottom: text.bottom },
    };
  },
  viewDirection() { return camera.getWorldDirection(new THREE.Vector3()).toArray(); },
};
