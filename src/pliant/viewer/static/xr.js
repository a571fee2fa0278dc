// VR: controllers grab a grip (trigger), move it, let go; each pulses with its hand's
// force at every accurate answer.
import * as THREE from 'three';
import { VRButton } from 'three/addons/webxr/VRButton.js';
import { renderer, scene, world } from './view.js';

// ``moved(handle)``: the page's reaction to a grip moved (it sends the pose).
export function setupXR(state, moved) {
  // The VR button only where the browser can enter VR (or the emulator is asked for): no
  // "VR NOT SUPPORTED" across the view of a desktop.
  if (navigator.xr) {
    navigator.xr.isSessionSupported('immersive-vr').then((ok) => {
      if (ok) document.body.appendChild(VRButton.createButton(renderer));
    }).catch(() => {});
  }
  const hands = [0, 1].map((i) => {
    const controller = renderer.xr.getController(i);
    controller.userData.index = i;
    controller.addEventListener('connected', (e) => { controller.userData.source = e.data; });
    controller.addEventListener('disconnected', () => { controller.userData.source = null; });
    controller.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3(0, 0, -0.1)])));
    scene.add(controller);
    controller.addEventListener('selectstart', () => grab(controller));
    controller.addEventListener('selectend', () => { controller.userData.held = null; });
    return controller;
  });
  // A controller holding a grip pulses with the force the hand must give there: full
  // strength at HAPTIC_FULL newtons (about the push a fitter gives with one hand, EN
  // 1005-3's range), in proportion below; each pulse is recorded (state.haptics).
  const HAPTIC_FULL = 50;  // N
  function pulseHands(msg) {
    for (const controller of hands) {
      const handle = controller.userData.held;
      const actuator = controller.userData.source?.gamepad?.hapticActuators?.[0];
      if (!handle || !actuator) continue;
      const load = msg.loads.find((l) => l.name === handle.name);
      if (!load) continue;
      const force = Math.hypot(...load.force);
      const value = Math.min(force / HAPTIC_FULL, 1);
      actuator.pulse(value, 60);
      state.haptics.push({ hand: controller.userData.source.handedness, grip: handle.name, force, value });
    }
  }
  function grab(controller) {
    const here = controller.getWorldPosition(new THREE.Vector3());
    let best = null, bestD = 0.15;  // m: how near a hand must be to take a grip
    const taken = new Set(hands.map((h) => h.userData.held).filter(Boolean));
    for (const handle of state.grips.values()) {
      if (!handle.userData.movable || taken.has(handle)) continue;  // one hand a grip
      const d = handle.getWorldPosition(new THREE.Vector3()).distanceTo(here);
      if (d < bestD) { best = handle; bestD = d; }
    }
    if (!best) return;
    // Keep the grip's pose relative to the controller while held.
    controller.updateMatrixWorld(true);
    best.updateMatrixWorld(true);
    controller.userData.held = best;
    controller.userData.offset = controller.matrixWorld.clone().invert().multiply(best.matrixWorld);
  }
  function followHands() {
    for (const controller of hands) {
      const handle = controller.userData.held;
      if (!handle) continue;
      controller.updateMatrixWorld(true);
      const target = controller.matrixWorld.clone().multiply(controller.userData.offset);
      const local = world.matrixWorld.clone().invert().multiply(target);
      const p = new THREE.Vector3(), q = new THREE.Quaternion(), s = new THREE.Vector3();
      local.decompose(p, q, s);
      if (p.distanceTo(handle.position) < 1e-5 && q.angleTo(handle.quaternion) < 1e-5) continue;
      handle.position.copy(p);
      handle.quaternion.copy(q);
      moved(handle);
    }
  }
  renderer.xr.addEventListener('sessionstart', () => {
    // VR is y up: turn the z-up world, and bring it in front of the user at table height.
    world.rotation.x = -Math.PI / 2;
    world.updateMatrixWorld(true);
    const box = new THREE.Box3().expandByObject(world);
    const c = box.getCenter(new THREE.Vector3());
    world.position.add(new THREE.Vector3(-c.x, 1.0 - c.y, -0.6 - c.z));
    state.xr = true;
  });
  renderer.xr.addEventListener('sessionend', () => {
    world.position.set(0, 0, 0);
    world.rotation.x = 0;
    state.xr = false;
  });
  return { hands, pulseHands, followHands };
}
