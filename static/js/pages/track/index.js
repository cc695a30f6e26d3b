// Track view (the chainage map): every run of a track along chainage, soft spots as a map
// (x chainage, y run, colour + size + symbol = severity), the defect register (runs aligned,
// soft spots merged into tracked defects with status, trend and priority) and the profiles of
// all runs around a chosen defect, the aggregated profile, alerts since a date, the track's
// limits and exports. The register is the only zone model: a track whose runs were never
// aligned gets it too, over its runs as logged.
// state.js: what the page loads; map.js: the chainage map; defects.js: the register;
// remove.js: deleting the track.

import { h, append, announce, fmtKmRange, messageBox, plural } from "../../dom.js";
import { ApiError, apiFetch } from "../../api.js";
import { aggregateCard, alertsCard, alignmentNotice, exportLinks, limitsCard } from "../../register.js";
import { stiffnessCard } from "../../stiffness.js";
import { loadTrackData, ranked, resolveTrack } from "./state.js";
import { mapCard } from "./map.js";
import { registerCards } from "./defects.js";
import { planCard } from "./plan.js";
import { deleteTrackControl } from "./remove.js";

export async function render(main, [ref], query) {
  let stopped = false;
  const isStopped = () => stopped;
  const heading = h("h1", { id: "track-title" }, "Track ", h("span", { class: "track-name" }, ref));
  const lead = h("p", { class: "lead", id: "track-lead" });
  const status = messageBox("info");
  main.append(heading, lead, status.el);

  const t0 = performance.now();
  // A route by id (every link of the dashboard) asks for the data at once: the API resolves an
  // id the same way everywhere. A name waits for its id (a name may hold "/").
  const early = /^\d+$/.test(ref) ? loadTrackData(encodeURIComponent(ref)) : null;
  let track;
  try {
    track = await resolveTrack(ref);
  } catch (err) {
    status.show(`Cannot load the tracks: ${err.message}`, "error");
    return null;
  }
  if (!track) {
    status.show(`There is no track “${ref}”.`, "error");
    return null;
  }
  const name = track.name;
  heading.querySelector(".track-name").textContent = name;
  const enc = encodeURIComponent(track.id);
  const { mapP, registerP } = early || loadTrackData(enc);
  let map;
  try {
    map = await mapP;
  } catch (err) {
    status.show(err instanceof ApiError && err.status === 404 ? `There is no track “${name}”.` : `Cannot load the chainage map: ${err.message}`, "error");
    return null;
  }
  const runs = map.runs || []; // the map shows processed runs only
  const trackInfo = map.track || {};
  append(lead, [
    `${plural(runs.length, "processed run")}`,
    map.chainage_min_m !== null && map.chainage_min_m !== undefined ? ` covering ${fmtKmRange(map.chainage_min_m, map.chainage_max_m, 0)}` : "",
    trackInfo.description ? ` · ${trackInfo.description}` : "",
    " · ",
    h("a", { href: "#/upload" }, "Upload another run"),
    " · ",
    h("a", { href: `#/tracks/${encodeURIComponent(track.id)}/quality`, id: "track-quality-link" }, "Track quality (EN 13848)"),
  ]);
  // The centerline's plan view and upload (issue 11), also before the first run.
  const plan = planCard(enc, { hasCenterline: track.has_centerline !== false });
  main.insertBefore(deleteTrackControl(track, track.n_runs ?? runs.length), status.el);
  if (runs.length === 0) {
    main.append(plan.section, h("p", { class: "muted" }, "No runs on this track yet."));
    return null;
  }
  main.appendChild(exportLinks(enc, track.id));

  // The map is drawn while the server still builds the register (it answers later than the
  // map on a long line): the two cost about the same, one on each side.
  const mapView = await mapCard(main, { enc, map, t0, isStopped });
  let register = [];
  let trackRuns = [];
  try {
    const [defects, runList] = await registerP;
    trackRuns = runList ? runList.data : [];
    if (defects) register = defects;
  } catch (err) {
    status.show(`Cannot load the defect register: ${err.message}`, "error");
  }
  // The map draws single runs' detections; over rough rail the register's separated soft
  // spots are what the track knows: say how many, beside the map's own count.
  const separated = register.filter((d) => d.source === "separated").length;
  const mapNote = document.getElementById("map-note");
  if (separated && mapNote) mapNote.append(" ", h("span", { id: "map-separated" }, `Besides: ${plural(separated, "soft spot")} separated from the rail's geometry across wheel loads (the top row; in the register below and on the stiffness map).`));
  const notice = alignmentNotice(trackRuns);
  if (notice) main.insertBefore(notice, mapView.section);
  // The aggregated profile is made of aligned runs only: no card for a track without any.
  const anyAligned = trackRuns.some((r) => r.alignment && r.alignment.status !== "unaligned");

  // ---- aggregated profile ---------------------------------------------------------------------
  let zones = ranked(register);
  const aggregate = anyAligned ? await aggregateCard(enc, () => zones) : null;
  if (aggregate) main.appendChild(aggregate.section);
  // Stiffness separated from rail geometry across passes of different wheel loads (issue 10).
  const stiffness = anyAligned ? stiffnessCard(enc) : null;
  if (stiffness) {
    main.appendChild(stiffness.section);
    const drawn = stiffness.render();
    // A run over rough rail links here: bring the map into view once it is drawn.
    if (query && query.get("view") === "stiffness") drawn.then(() => stiffness.section.scrollIntoView());
  }

  // ---- register (ranked by priority) ---------------------------------------------------------
  const registerView = registerCards(main, { enc, getZones: () => zones, isStopped });
  main.appendChild(plan.section);
  plan.showRuns(runs);
  plan.showDefects(() => zones, (zone) => registerView.showZone(zone));
  // The map's top row: the separated soft spots, ranked as in the register.
  const separatedOnMap = () => mapView.showSeparated(zones.filter((d) => d.source === "separated"), registerView.select);
  separatedOnMap();

  // ---- alerts and limits ---------------------------------------------------------------------
  // Alerts and limits serve the maintenance of aligned tracks (a track whose runs were never
  // aligned has its register as logged, but nothing to plan from yet).
  if (anyAligned) {
    const alerts = alertsCard(enc, () => register);
    const limits = limitsCard(enc, async () => {
      register = await apiFetch(`/api/v1/tracks/${enc}/defects`);
      zones = ranked(register);
      registerView.draw();
      await separatedOnMap();
      if (aggregate) await aggregate.render();
      if (stiffness) await stiffness.render();
      await alerts.load();
    });
    main.appendChild(h("div", { class: "track-lower" }, alerts.section, limits.section));
    limits.load();
    alerts.load();
  }

  if (zones.length) registerView.showZone(zones[0]);
  if (aggregate) aggregate.render();
  announce(`Track ${name}: ${plural(runs.length, "run")}, ${plural(zones.length, "zone")}.`);
  return () => {
    stopped = true;
    mapView.stop();
  };
}
