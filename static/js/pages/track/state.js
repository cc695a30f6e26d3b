// Track page state: which track a route names, the data the page loads for it, and the
// severity classes the chainage map draws with.

import { apiFetch, apiFetchAll, apiGetOptional } from "../../api.js";

// Severity classes by depth (mm): the symbol and size repeat what the colour says, so the map
// reads without colour vision.
export const CLASSES = [
  { max: 0.15, symbol: "circle", label: "< 0.15 mm" },
  { max: 0.3, symbol: "square", label: "0.15–0.3 mm" },
  { max: 0.5, symbol: "diamond", label: "0.3–0.5 mm" },
  { max: Infinity, symbol: "x", label: "≥ 0.5 mm" },
];

export function severityClass(depth) {
  return CLASSES.findIndex((c) => depth < c.max);
}

/**
 * The track a route names (#/tracks/{id} or #/tracks/{name}), asked of the API, which
 * resolves an id or a name (null when there is none). Later calls use the id: a name may
 * hold "/" or other characters that do not survive a URL path.
 */
export async function resolveTrack(ref) {
  return apiGetOptional(`tracks/${encodeURIComponent(ref)}`);
}

/**
 * Ask for the map, the register (aligned runs; every run when none is aligned) and the track's
 * runs at once: the register is computed while the map travels. Returns {mapP, registerP}.
 */
export function loadTrackData(enc) {
  const mapP = apiFetch(`/api/v1/views/tracks/${enc}/chainage-map?bins=1200&zones=false`);
  const registerP = Promise.all([
    apiGetOptional(`/api/v1/tracks/${enc}/defects`),
    apiFetchAll(`/api/v1/runs?track=${enc}`).then((data) => ({ data })).catch(() => null),
  ]);
  // Awaited by the caller (unless the track turns out not to exist): no unhandled rejection.
  mapP.catch(() => {});
  registerP.catch(() => {});
  return { mapP, registerP };
}

/** The register's defects with their rank (the register comes most urgent first). */
export function ranked(defects) {
  return defects.map((d, i) => ({ ...d, rank: i + 1 }));
}
