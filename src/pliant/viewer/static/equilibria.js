// The pose's other equilibria (the server's search, best first): a table of their
// stability, energy and bow side; pointing at a row draws that shape as a dashed line
// beside the tube, and Use makes it the accurate answer the session follows on. A move
// of a grip makes the list stale (it answered the earlier pose).
import * as THREE from 'three';
import { $, esc, fmt, fmtEnergy } from './util.js';
import { world } from './view.js';

const CANDIDATE = 0x00838f;  // the shape pointed at: a dashed line

// The panel's part, wired to the page's state and its way of sending a message.
export function setupEquilibria(state, send) {
  let candidate = null;
  $('find').onclick = () => {
    send({ type: 'equilibria', budget: 10 });
    $('find').disabled = true;
    $('find-status').textContent = 'searching (up to 10 s)…';
  };
  function onEquilibria(msg) {
    state.equilibria = msg;
    $('find').disabled = false;
    const box = $('equilibria');
    box.classList.toggle('stale', !msg.current);
    if (!msg.ok) {
      $('find-status').textContent = `search failed: ${msg.error}`;
      box.innerHTML = '';
      return;
    }
    $('find-status').textContent = `${msg.options.length} found in ${msg.seconds.toFixed(1)} s` +
      (msg.current ? '' : ' for an earlier pose');
    const shown = state.accurate ? state.accurate.position : null;
    const rows = msg.options.map((o, k) => {
      const same = shown && shown.length === o.position.length &&
        o.position.every((p, i) => Math.hypot(p[0] - shown[i][0], p[1] - shown[i][1], p[2] - shown[i][2]) < 1e-6);
      return `<tr data-k="${k}" class="${same ? 'shown' : ''}" title="${esc(o.notes.join('; '))}">` +
        `<td>${k + 1}</td><td>${esc(o.verdict)}</td><td class="num">${fmtEnergy(o.potential_energy)}</td>` +
        `<td>${esc(o.bows)}</td><td class="num">${fmt(Math.abs(o.max_moment))}</td>` +
        `<td>${same ? 'shown' : msg.current ? '<button>Use</button>' : ''}</td></tr>`;
    }).join('');
    box.innerHTML = msg.options.length ? `<table><tr class="muted"><td>#</td><td>stability</td>` +
      `<td class="num" title="potential energy (elastic, weight and applied loads)">E [J]</td><td>bows</td>` +
      `<td class="num" title="largest bending moment">M [N m]</td><td></td></tr>${rows}</table>` : '';
    for (const tr of box.querySelectorAll('tr[data-k]')) {
      const k = Number(tr.dataset.k);
      tr.onmouseenter = () => showCandidate(k);
      tr.onmouseleave = () => showCandidate(null);
      tr.onclick = () => showCandidate(k);
      const use = tr.querySelector('button');
      if (use) use.onclick = (e) => { e.stopPropagation(); send({ type: 'choose', option: k }); };
    }
  }

  function showCandidate(k) {
    if (candidate) { candidate.geometry.dispose(); world.remove(candidate); candidate = null; }
    for (const tr of $('equilibria').querySelectorAll('tr[data-k]')) tr.classList.toggle('on', Number(tr.dataset.k) === k);
    if (k === null || !state.equilibria) return;
    const option = state.equilibria.options[k];
    const geometry = new THREE.BufferGeometry().setFromPoints(option.position.map((p) => new THREE.Vector3(...p)));
    candidate = new THREE.Line(geometry, new THREE.LineDashedMaterial({ color: CANDIDATE, dashSize: 0.02, gapSize: 0.012 }));
    candidate.computeLineDistances();
    candidate.name = 'candidate';
    world.add(candidate);
  }
  function staleEquilibria() {
    const msg = state.equilibria;
    if (!msg || !msg.current) return;
    onEquilibria({ ...msg, current: false });
  }
  return { onEquilibria, staleEquilibria };
}
