// Track quality in EN 13848 terms (#/tracks/{track}/quality): sections coloured by quality
// class along chainage (D1 SD per section), the D1/D2 longitudinal levels with the isolated
// defects, the exceedance list, per-section passes and repeatability, what rests on the
// loaded level, and the CSV / GeoJSON exports. Everything comes from GET /tracks/{t}/quality.

import { h, append, announce, fmt, messageBox, plural, scrollTable } from "../dom.js";
import { apiFetch } from "../api.js";
import { baseLayout, CONFIG, loadPlotly } from "../plots.js";

// Classes A (best) to E: colour and the letter on each bar say the same (no colour only).
const CLASS_COLORS = { A: "#009E73", B: "#56B4E9", C: "#F0E442", D: "#E69F00", E: "#D55E00" };
const LEVEL_LABEL = { immediate: "immediate action", intervention: "intervention", alert: "alert" };
const LEVEL_SYMBOL = { immediate: "x", intervention: "diamond", alert: "square" };
// The API's basis of a figure, in the words of the column "Level from" (its header explains).
const BASIS_LABEL = { unloaded: "separated geometry", loaded: "loaded profile", mixed: "both" };
const BASIS_TITLE = "Which level the figure comes from: the rail geometry separated from the support's stiffness (unloaded), the aggregated loaded profile of the runs (soft supports' dips included), or both over parts of the section.";
const basisOf = (b) => BASIS_LABEL[b] || b;
/** Column headers; "Level from" carries its explanation as a tooltip. */
const headers = (names) => h("thead", {}, h("tr", {}, ...names.map((c) => h("th", { scope: "col", title: c === "Level from" ? BASIS_TITLE : null }, c))));

function sectionTraces(q) {
  const secs = q.sections.filter((s) => s.d1_sd_mm !== null);
  return Object.keys(CLASS_COLORS).map((cls) => {
    const mine = secs.filter((s) => s.quality_class === cls);
    // one filled step per section (start to end at its SD; null between sections): the
    // dashboard's plotly bundle has scatter and heatmap only, no bar trace
    return {
      type: "scatter", mode: "lines", fill: "tozeroy", connectgaps: false, name: `Class ${cls}`, meta: `class-${cls}`,
      x: mine.flatMap((s) => [s.start_m, s.end_m, null]), y: mine.flatMap((s) => [s.d1_sd_mm, s.d1_sd_mm, null]),
      line: { color: "#1b1f24", width: 1 }, fillcolor: CLASS_COLORS[cls],
      hovertemplate: `%{x:.0f} m: D1 SD %{y:.2f} mm (class ${cls})<extra></extra>`,
    };
  }).filter((t) => t.x.length);
}

function levelTraces(q) {
  const t = q.traces || { chainage_m: [], d1_mm: [], d2_mm: [] };
  const traces = [
    { type: "scatter", mode: "lines", name: "D1 (3–25 m)", meta: "d1", x: t.chainage_m, y: t.d1_mm, line: { color: "#0072B2", width: 1.2 }, connectgaps: false,
      hovertemplate: "%{x:.0f} m: D1 %{y:.2f} mm<extra></extra>" },
    { type: "scatter", mode: "lines", name: `D2 (${q.d2_band_m[0]}–${q.d2_band_m[1]} m)`, meta: "d2", x: t.chainage_m, y: t.d2_mm, line: { color: "#CC79A7", width: 1.2 }, connectgaps: false,
      hovertemplate: "%{x:.0f} m: D2 %{y:.2f} mm<extra></extra>" },
  ];
  for (const lv of ["alert", "intervention", "immediate"]) {
    const mine = q.defects.filter((d) => d.level === lv);
    if (mine.length) {
      traces.push({ type: "scatter", mode: "markers", name: LEVEL_LABEL[lv], meta: `defect-${lv}`,
        x: mine.map((d) => d.peak_m), y: mine.map((d) => d.value_mm),
        marker: { symbol: LEVEL_SYMBOL[lv], size: 9, color: "#7a0019" },
        hovertemplate: `%{x:.1f} m: %{y:.2f} mm (${LEVEL_LABEL[lv]})<extra></extra>` });
    }
  }
  return traces;
}

function sectionsTable(q) {
  const rows = q.sections.map((s) => h("tr", {},
    h("td", {}, `${fmt(s.start_m, 0)}–${fmt(s.end_m, 0)}`),
    h("td", {}, s.d1_sd_mm === null ? "—" : fmt(s.d1_sd_mm, 2)),
    h("td", {}, s.d2_sd_mm === null ? "—" : fmt(s.d2_sd_mm, 2)),
    h("td", {}, s.quality_class || "—"),
    h("td", {}, String(s.n_passes)),
    h("td", {}, s.days_since_last_pass === null ? "—" : fmt(s.days_since_last_pass, 0)),
    h("td", {}, s.repeatability_d1_mm === null ? "—" : fmt(s.repeatability_d1_mm, 2)),
    h("td", {}, s.speed_kmh === null ? "—" : fmt(s.speed_kmh, 0)),
    h("td", {}, basisOf(s.basis)),
  ));
  return h("table", { id: "quality-sections", class: "data" },
    h("caption", {}, `Sections of ${fmt(q.section_m, 0)} m`),
    headers(["Chainage (m)", "D1 SD (mm)", "D2 SD (mm)", "Class", "Passes", "Days since last", "Repeatability D1, 95 % (mm)", "Line speed (km/h)", "Level from"]),
    h("tbody", {}, ...rows));
}

function defectsTable(q) {
  const when = (c) => (!c ? "—" : c.reached ? "reached" : c.date ? `${c.date.slice(0, 10)} (${c.earliest ? c.earliest.slice(0, 10) : "?"} – ${c.latest ? c.latest.slice(0, 10) : "open"})` : "not growing");
  const rows = q.defects.map((d) => h("tr", {},
    h("td", {}, fmt(d.peak_m, 1)), h("td", {}, d.band), h("td", {}, fmt(d.value_mm, 2)),
    h("td", {}, LEVEL_LABEL[d.level]), h("td", {}, d.speed_kmh === null ? "unknown (strictest)" : fmt(d.speed_kmh, 0)),
    h("td", {}, basisOf(d.basis)), h("td", {}, when(d.next_limit)),
  ));
  return h("table", { id: "quality-defects", class: "data" },
    h("caption", {}, "Isolated defects (mean to peak) against the speed-class limits"),
    headers(["Peak (m)", "Band", "Value (mm)", "Level", "Line speed (km/h)", "Level from", "Next limit expected"]),
    // an empty table would read as not loaded: say there is none
    h("tbody", {}, ...(rows.length ? rows : [h("tr", {}, h("td", { colspan: 7, class: "muted" }, "None: no isolated defect at a limit level."))])));
}

export async function render(main, [ref], query) {
  const sectionM = Number(query && query.get("section_m")) || 200;
  const enc = encodeURIComponent(ref);
  const heading = h("h1", {}, "Track quality ", h("span", { class: "track-name" }, ref));
  const status = messageBox("info");
  main.append(heading, status.el);
  let q;
  try {
    q = await apiFetch(`/api/v1/tracks/${enc}/quality?section_m=${sectionM}&traces=true`);
  } catch (err) {
    status.show(`Cannot load the track's quality: ${err.message}`, "error");
    return null;
  }
  heading.querySelector(".track-name").textContent = q.track;
  const tid = encodeURIComponent(q.track_id);
  append(main, [
    h("p", { class: "lead" },
      `Longitudinal level per EN 13848-1 (D1 3–25 m, D2 ${q.d2_band_m[0]}–${q.d2_band_m[1]} m, zero-phase Butterworth), `,
      `${plural(q.sections.length, "section")}, ${plural(q.defects.length, "isolated defect")}. `,
      h("a", { href: `#/tracks/${tid}` }, "Back to the track"), " · ",
      h("a", { href: `/api/v1/tracks/${tid}/quality.csv?section_m=${sectionM}`, download: "" }, "CSV"), " · ",
      h("a", { href: `/api/v1/tracks/${tid}/quality.geojson?section_m=${sectionM}`, download: "" }, "GeoJSON (on the centerline)")),
  ]);
  if (q.notes.length) main.append(h("ul", { class: "message info", id: "quality-notes" }, ...q.notes.map((n) => h("li", {}, n))));
  if (q.unverified_limits.length) main.append(h("p", { class: "muted", id: "quality-unverified" }, `Product defaults not verified against EN 13848-5/-6 (docs/method.md): ${q.unverified_limits.join(", ")}. Set the track's own with PUT /tracks/{track}/quality-limits.`));
  const facts = [];
  if (q.repeatability && q.repeatability.r95_mm !== null) {
    facts.push(h("li", {}, `Repeatability between successive passes (${q.repeatability.band_m[0]}–${q.repeatability.band_m[1]} m): 95 % of differences within ${fmt(q.repeatability.r95_mm, 2)} mm.`));
  }
  for (const o of q.observability || []) {
    const blind = o.unobservable_m.length ? `; neither signal carries ${o.unobservable_m.map((r) => `${fmt(r[0], 1)}–${fmt(r[1], 1)} m`).join(", ")}` : "; the two signals together see all of 3–70 m";
    const wheelbase = (o.wheelbase_nulls_m || []).length ? `, its bogies' wheelsets cancel ${o.wheelbase_nulls_m.map((x) => fmt(x, 1)).join(", ")} m` : "";
    facts.push(h("li", {}, `${o.vehicle} at ${fmt(o.speed_mps, 0)} m/s: bounce blind at ${o.bounce_nulls_m.map((x) => fmt(x, 1)).join(", ")} m, pitch blind at ${o.pitch_nulls_m.map((x) => fmt(x, 1)).join(", ")} m${wheelbase}${blind}.`));
  }
  for (const sv of q.survey_comparison || []) {
    const worst = sv.sections.reduce((m, r) => Math.max(m, Math.abs(r.d1_sd_diff_mm ?? 0)), 0);
    facts.push(h("li", {}, `Against the recording car “${sv.name || `survey ${sv.survey_id}`}”: D1 SD differs by at most ${fmt(worst, 2)} mm over ${plural(sv.sections.length, "section")} (table in the report).`));
  }
  if (facts.length) main.append(h("ul", { id: "quality-facts" }, ...facts));
  const classChart = h("div", { id: "quality-classes", class: "plot", role: "figure", "aria-label": "D1 standard deviation per section, coloured by quality class" });
  const levelChart = h("div", { id: "quality-levels", class: "plot", role: "figure", "aria-label": "D1 and D2 longitudinal level along chainage with the isolated defects" });
  main.append(
    h("section", { class: "card", "aria-labelledby": "quality-classes-h" }, h("h2", { id: "quality-classes-h" }, "Sections by quality class"), classChart,
      // the tables scroll in their card: on a phone they are wider than the screen
      scrollTable("Sections by quality class", sectionsTable(q))),
    h("section", { class: "card", "aria-labelledby": "quality-levels-h" }, h("h2", { id: "quality-levels-h" }, "Longitudinal level and isolated defects"), levelChart,
      scrollTable("Isolated defects", defectsTable(q))),
  );
  const Plotly = await loadPlotly();
  await Plotly.newPlot(classChart, sectionTraces(q), baseLayout({ barmode: "overlay", yaxis: { title: { text: "D1 SD (mm)" }, rangemode: "tozero" } }), CONFIG);
  await Plotly.newPlot(levelChart, levelTraces(q), baseLayout({ yaxis: { title: { text: "Level (mm)" } } }), CONFIG);
  announce(`Track ${q.track} quality: ${plural(q.sections.length, "section")}, ${plural(q.defects.length, "defect")}.`);
  return () => {
    try { Plotly.purge(classChart); Plotly.purge(levelChart); } catch { /* already gone */ }
  };
}
