// Made by `python -m pliant.viewer.protocol` from pliant/viewer/protocol.py (the
// pydantic models): do not edit. The wire protocol's version, the messages the
// page may send (type: fields) and those the server answers with.
export const VERSION = 1;
export const CLIENT = Object.freeze({
  "hello": [],
  "move": [
    "grip",
    "position",
    "tangent",
    "seq"
  ],
  "mode": [
    "grip",
    "mode",
    "force",
    "moment"
  ],
  "solve": [],
  "save": [
    "name"
  ],
  "load": [
    "name"
  ],
  "equilibria": [
    "budget"
  ],
  "choose": [
    "option"
  ]
});
export const SERVER = Object.freeze({
  "scene": [
    "name",
    "file",
    "dimension",
    "part",
    "obstacles",
    "grips",
    "margin",
    "envelopes",
    "path",
    "ports"
  ],
  "frame": [
    "seq",
    "index",
    "s",
    "curve",
    "curvature",
    "contacts",
    "interference",
    "converged",
    "drift",
    "pending",
    "seconds",
    "warnings"
  ],
  "accurate": [
    "index",
    "ok",
    "error",
    "s",
    "position",
    "curvature",
    "bending_moment",
    "loads",
    "contacts",
    "interference",
    "fitted",
    "branches",
    "min_bend_radius",
    "min_bend_radius_s",
    "allowed_bend_radius",
    "stable",
    "smallest_eigenvalue",
    "residual",
    "iterations",
    "solve_seconds",
    "warnings",
    "notes",
    "verdict"
  ],
  "equilibria": [
    "index",
    "current",
    "ok",
    "error",
    "seconds",
    "options"
  ],
  "saved": [
    "name",
    "folder"
  ],
  "error": [
    "message",
    "field"
  ]
});
// A client message, checked against CLIENT: a type or field the server does not
// take is the page's bug, thrown here and not sent.
export function message(type, fields = {}) {
  const known = CLIENT[type];
  if (!known) throw new Error(`protocol: no client message '${type}'`);
  for (const name of Object.keys(fields)) {
    if (!known.includes(name)) {
      throw new Error(`protocol: ${type} has no field '${name}'`);
    }
  }
  return JSON.stringify({ v: VERSION, type, ...fields });
}
