// Sampled series along the chainage (levels, geometry): reading them between samples.

/**
 * Linear interpolation of the series (xs, ys) at x; xs increasing (m), ys in any unit with
 * null at gaps. Strict (the default): null outside [xs[0], xs[last]] or next to a gap, so
 * that a difference of two series is only drawn where both are known. `nearest: true`
 * gives the end value outside and the known neighbour next to a gap instead: where a marker
 * sits on a drawn line.
 */
export function interpAt(xs, ys, x, { nearest = false } = {}) {
  const last = xs.length - 1;
  if (last < 0) return null;
  if (x < xs[0] || x > xs[last]) return nearest ? ys[x < xs[0] ? 0 : last] : null;
  let lo = 0;
  let hi = last;
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (xs[mid] <= x) lo = mid;
    else hi = mid;
  }
  const a = ys[lo];
  const b = ys[hi];
  if (a === null || b === null) return nearest ? (a ?? b) : null;
  return xs[hi] === xs[lo] ? a : a + ((b - a) * (x - xs[lo])) / (xs[hi] - xs[lo]);
}
