// Small helpers the page's modules share: an element by id, HTML escaping, names as ids,
// numbers for people, linear interpolation.
export const $ = (id) => document.getElementById(id);
export function interp(x, xs, ys) {
  if (!xs.length) return 0;
  if (x <= xs[0]) return ys[0];
  let lo = 0, hi = xs.length - 1;
  if (x >= xs[hi]) return ys[hi];
  while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (xs[mid] <= x) lo = mid; else hi = mid; }
  const t = (x - xs[lo]) / (xs[hi] - xs[lo] || 1);
  return ys[lo] + t * (ys[hi] - ys[lo]);
}
export function slug(name) { return name.replace(/[^A-Za-z0-9_-]/g, '_'); }
export function esc(text) { return String(text).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c])); }
// x with d decimals; a value that rounds to zero reads 0, not -0.000 (round-off).
export function fixed(x, d) { const t = x.toFixed(d); return Number(t) === 0 ? t.replace('-', '') : t; }
export function fmt(x) { return x >= 100 ? x.toFixed(0) : x >= 1 ? x.toFixed(2) : x.toPrecision(2); }
export function fmtEnergy(x) { return Math.abs(x) >= 1e4 || (Math.abs(x) < 1e-3 && x !== 0) ? x.toExponential(3) : x.toFixed(4); }
