// Track view: the stiffness map. Support stiffness in % of nominal separated from rail geometry
// across the track's passes of different wheel loads (and surveys), coloured by the track's
// stiffness-loss limits, its band, the unloaded geometry below it, the separated soft spots
// and the passes that contributed with their wheel loads. Where the passes cannot separate
// the two, the card says so in plain words and draws no stiffness.

import { h, fmt, fmtKm, fmtKmRange, messageBox, scrollTable } from "./dom.js";
import { apiFetch } from "./api.js";
import { baseLayout, COLORS, CONFIG, loadPlotly } from "./plots.js";
import { provisionalBanner, provisionalLabel, spotsAre } from "./provisional.js";

// Loss classes against the track's limits: colour and symbol say the same (no colour only).
const LEVELS = [
  { key: "immediate", label: "immediate action", color: "#7a0019", symbol: "x" },
  { key: "intervention", label: "intervention", color: "#D55E00", symbol: "diamond" },
  { key: "alert", label: "alert", color: "#E69F00", symbol: "square" },
];
const BELOW = { key: "below", label: "below the limits", color: "#0072B2", symbol: "circle" };

/** The limit level a stiffness loss (%) reaches with the track's limits, or BELOW. */
export function lossLevel(lossPct, limits) {
  for (const lv of LEVELS) {
    const limit = limits ? limits[`${lv.key}_loss_pct`] : null;
    if (limit !== null && limit !== undefined && lossPct >= limit) return lv;
  }
  return BELOW;
}

function stiffnessTraces(st, limits) {
  const x = st.chainage_m;
  const pct = st.k_rel.map((k) => (k === null ? null : 100 * k));
  const lo = st.k_rel_lo.map((k) => (k === null ? null : 100 * k));
  const hi = st.k_rel_hi.map((k) => (k === null ? null : 100 * k));
  const traces = [
    { x, y: hi, type: "scatter", mode: "lines", line: { width: 0 }, hoverinfo: "skip", showlegend: false, connectgaps: false, yaxis: "y" },
    { x, y: lo, type: "scatter", mode: "lines", line: { width: 0 }, fill: "tonexty", fillcolor: "rgba(0, 114, 178, 0.15)", name: "95 % band", hoverinfo: "skip", connectgaps: false, yaxis: "y" },
    { x, y: pct, type: "scatter", mode: "lines", name: "Stiffness (% of nominal)", line: { color: COLORS.fused, width: 1.5 }, connectgaps: false, yaxis: "y", meta: "stiffness",
      hovertemplate: "%{x:.2f} m: %{y:.0f} % of nominal<extra></extra>" },
  ];
  // each point below nominal coloured by the limit its loss reaches
  for (const lv of [...LEVELS].reverse()) {
    const xs = [];
    const ys = [];
    pct.forEach((p, i) => {
      if (p !== null && lossLevel(100 - p, limits).key === lv.key) { xs.push(x[i]); ys.push(p); }
    });
    if (xs.length) {
      traces.push({ x: xs, y: ys, type: "scatter", mode: "markers", name: `Loss ≥ ${lv.label} limit`, meta: `level-${lv.key}`,
        marker: { color: lv.color, symbol: lv.symbol, size: 6 }, yaxis: "y", hovertemplate: `%{x:.2f} m: %{y:.0f} % (${lv.label})<extra></extra>` });
    }
  }
  traces.push({ x, y: st.geometry_mm, type: "scatter", mode: "lines", name: "Unloaded geometry (mm)", line: { color: "#000000", width: 1 }, connectgaps: false, yaxis: "y2", xaxis: "x", meta: "geometry",
    hovertemplate: "%{x:.2f} m: %{y:.2f} mm<extra></extra>" });
  return traces;
}

function spotShapes(spots, limits) {
  return spots.map((s) => {
    const lv = lossLevel(s.stiffness_loss_pct, limits);
    return { type: "rect", xref: "x", yref: "paper", x0: s.start_m, x1: s.end_m, y0: 0, y1: 1, fillcolor: lv.color, opacity: 0.15, line: { width: 0 }, name: "separated-spot" };
  });
}

function contributorsList(st) {
  if (!st.contributors.length) return h("p", { class: "muted" }, "No pass contributes here.");
  const items = st.contributors
    .slice()
    .sort((a, b) => a.mean_force_n - b.mean_force_n)
    .map((c) => h("li", {}, `${c.kind === "survey" ? "Survey" : "Run"} ${c.id}`, c.vehicle ? ` (${c.vehicle})` : "", `: ${fmt(c.mean_force_n / 1000, 0)} kN per wheel`));
  return h("ul", { class: "contributors", id: "stiffness-contributors" }, ...items);
}

function spotsTable(spots, limits) {
  if (!spots.length) return h("p", { class: "muted", id: "stiffness-spots" }, "No soft spot where the stiffness is separated.");
  // numeric headers aligned with their right-aligned columns
  const head = h("tr", {}, ...["Zone", "Peak", "Loss (%)", "Band (%)", "Level"].map((t) => h("th", { scope: "col", class: t === "Level" ? null : "num" }, t)));
  const rows = spots.map((s) => h("tr", {},
    h("td", { class: "num" }, fmtKmRange(s.start_m, s.end_m), provisionalLabel(s)),
    h("td", { class: "num" }, fmtKm(s.peak_m)),
    h("td", { class: "num" }, fmt(s.stiffness_loss_pct, 0)),
    h("td", { class: "num" }, `${fmt(s.loss_lo_pct, 0)}–${fmt(s.loss_hi_pct, 0)}`),
    h("td", {}, lossLevel(s.stiffness_loss_pct, limits).label)));
  // in a box that scrolls sideways: on a phone the table is wider than the card
  return scrollTable("Soft spots where the stiffness is separated",
    h("table", { class: "data", id: "stiffness-spots" }, h("thead", {}, head), h("tbody", {}, ...rows)));
}

const UPDATING_NOTE = "a run stored a moment ago is being separated with the others; this map shows the state before it and reloads by itself.";
const RELOAD_MS = 3000;
const MAX_RELOADS = 20; // a minute; a separation that takes longer shows on the next visit

/** The stiffness card of a track (``enc``: its encoded id); ``render()`` (re)loads it. */
export function stiffnessCard(enc) {
  const div = h("div", { class: "plot plot-stiffness", id: "stiffness-map", role: "figure", "aria-label": "Stiffness map: support stiffness in percent of nominal along chainage, coloured by the track's loss limits, with the unloaded rail geometry below" });
  const status = messageBox("info");
  status.el.id = "stiffness-message";
  const note = h("p", { class: "hint", id: "stiffness-note" });
  const details = h("div", { class: "stiffness-details" });
  const section = h("section", { class: "card", "aria-labelledby": "stiffness-h", id: "stiffness-card" },
    h("div", { class: "section-head" },
      h("h2", { id: "stiffness-h" }, "Stiffness map"),
      h("a", { class: "button small", id: "export-stiffness-csv", href: `/api/v1/tracks/${enc}/stiffness?format=csv` }, "Stiffness (CSV)")),
    h("p", { class: "hint" }, "Support stiffness in % of nominal, separated from the rail's own geometry by comparing passes of different wheel loads (and surveys); points coloured by the loss limit they reach; the band is its 95 % interval. Below: the unloaded rail geometry."),
    status.el, div, note, details);
  let reloads = 0; // while a just-stored run's separation is redone (st.updating)
  const render = async () => {
    let st;
    let limits = null;
    try {
      [st, limits] = await Promise.all([
        apiFetch(`/api/v1/tracks/${enc}/stiffness`),
        apiFetch(`/api/v1/tracks/${enc}/limits`).catch(() => null),
      ]);
    } catch (err) {
      status.show(`Cannot load the stiffness: ${err.message}`, "error");
      return;
    }
    const said = st.updating ? `Updating: ${UPDATING_NOTE}${st.message ? ` ${st.message}` : ""}` : st.message;
    if (said) status.show(said, st.separable && !st.updating ? "info" : "warning");
    else status.hide();
    if (st.updating && reloads < MAX_RELOADS) {
      reloads += 1;
      setTimeout(() => { if (section.isConnected) render(); }, RELOAD_MS);
    } else if (!st.updating) reloads = 0;
    details.replaceChildren(
      h("h3", {}, "Soft spots (separated)"),
      // the spots when some are provisional, else the map itself (its passes' vehicles)
      provisionalBanner(st.soft_spots, spotsAre, "stiffness-provisional")
        || provisionalBanner([st], () => "This stiffness map is", "stiffness-provisional") || "",
      spotsTable(st.soft_spots, limits),
      h("h3", {}, "Contributing passes"), contributorsList(st));
    if (!st.n || !st.separable) {
      div.hidden = true;
      note.textContent = st.n ? "No stiffness is drawn: nowhere on this track do the passes span enough wheel load." : "No aligned pass yet.";
      return;
    }
    div.hidden = false;
    // On a phone the legend wraps to several lines: below the plot it covers nothing.
    const narrow = div.clientWidth > 0 && div.clientWidth < 560;
    const layout = baseLayout({
      height: narrow ? 560 : 440, hovermode: "closest", shapes: spotShapes(st.soft_spots, limits),
      margin: narrow ? { l: 52, r: 8, t: 16, b: 150 } : { l: 64, r: 16, t: 16, b: 52 },
      legend: narrow ? { orientation: "h", x: 0, y: -0.12, yanchor: "top", font: { size: 10 } } : { orientation: "h", x: 0, y: 1.1 },
      // the chainage axis (ticks and title) sits under the stiffness plot: the gap down to
      // the geometry plot holds both, so its title does not cross the geometry trace
      yaxis: { title: { text: "Stiffness (% of nominal)" }, domain: [0.47, 1], gridcolor: "#e3e6ea", automargin: true },
      yaxis2: { title: { text: "Geometry (mm)" }, domain: [0, 0.27], gridcolor: "#e3e6ea", automargin: true },
    });
    await (await loadPlotly()).react(div, stiffnessTraces(st, limits), layout, CONFIG);
    const sep = Math.round(100 * st.separable_fraction);
    note.textContent = `${st.n.toLocaleString()} grid points, ${sep} % of them separable; ${st.soft_spots.length} soft spot${st.soft_spots.length === 1 ? "" : "s"}.`;
  };
  return { section, render };
}
