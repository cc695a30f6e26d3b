// The track page's chainage map: every run along chainage, soft spots as markers (x chainage,
// y run, colour + size + symbol = severity) over an optional level background; thousands of
// spots (a long line) merged per run into cells of a few pixels. Zooming asks the server for
// that window only.

import { h, fmt, fmtDate, plural } from "../../dom.js";
import { apiFetch } from "../../api.js";
import { baseLayout, CONFIG, loadPlotly, viridis, zoomControls } from "../../plots.js";
import { CLASSES, severityClass } from "./state.js";

/** The map's top row: the register's soft spots separated from the rail's geometry across
 * wheel loads (over rough rail no single run sees them). */
export const SEPARATED_ROW = { wide: "Separated across loads", narrow: "Separated" };

function legendBox() {
  return h("ul", { class: "severity-legend", "aria-label": "Severity classes by depth" },
    CLASSES.map((c, i) => h("li", {}, h("span", { class: `sym sym-${c.symbol}`, "aria-hidden": "true", style: `--c:${viridis(1 - (i + 0.5) / CLASSES.length)}` }), c.label)));
}

function heatmapTrace(heat, labels, visible) {
  return {
    type: "heatmap", meta: "heatmap", name: "Level", x: heat.x, y: labels, z: heat.z,
    colorscale: [[0, "#4b5563"], [0.5, "#d1d5db"], [1, "#f9fafb"]],
    zmid: 0, showscale: false, visible, hoverongaps: false,
    hovertemplate: "%{x:.0f} m · %{y}<br>lowest level %{z:.2f} mm<extra></extra>",
  };
}

/** The median extent of the spots (m), 0 when there are none. */
function medianExtent(s) {
  const ext = s.peak_m.map((_, i) => s.end_m[i] - s.start_m[i]).sort((a, b) => a - b);
  return ext.length ? ext[ext.length >> 1] : 0;
}

/** Above this many soft spots the map merges them into cells (see `spotCells`): each SVG
 * marker is a DOM node styled one by one, and ~7 000 of them (a 100 km line) took plotly
 * 1.5-3 s to draw, a grid of cells 0.3-0.6 s. A zoomed window with fewer spots gets markers. */
export const MAX_MARKERS = 1500;

/** Width of a merged cell, px: its coloured core is `CELL_PX - 2`, framed by 1 px of dark on
 * each side like a marker's outline (the pale end of the colour scale on white needs it). */
export const CELL_PX = 5;

/**
 * The soft spots merged per run (row) and per `CELL_PX` pixels of chainage, for a map drawn at
 * `metresPerPixel`. Cells are aligned to multiples of their width (m). Returns
 * {x0, dx, z, count, customdata}: x0 the first column's centre and dx the cells' width (m),
 * and per row (run index) and column z the deepest spot's depth (mm, null where no spot is),
 * count the number of spots, customdata [first start (m), last end (m), the deepest's peak (m),
 * its stiffness loss (%)].
 */
export function spotCells(s, nRows, metresPerPixel) {
  const width = CELL_PX * metresPerPixel;
  const col = s.peak_m.map((p) => Math.floor(p / width));
  const c0 = col.reduce((a, c) => Math.min(a, c), Infinity);
  const nCols = col.reduce((a, c) => Math.max(a, c), -Infinity) - c0 + 1;
  const z = Array.from({ length: nRows }, () => new Array(nCols).fill(null));
  const count = Array.from({ length: nRows }, () => new Array(nCols).fill(0));
  const customdata = Array.from({ length: nRows }, () => new Array(nCols).fill(null));
  s.peak_m.forEach((p, i) => {
    const r = s.run_index[i];
    const c = col[i] - c0;
    const cd = customdata[r][c];
    count[r][c] += 1;
    if (cd === null) customdata[r][c] = [s.start_m[i], s.end_m[i], p, s.stiffness_loss_pct[i]];
    else {
      cd[0] = Math.min(cd[0], s.start_m[i]);
      cd[1] = Math.max(cd[1], s.end_m[i]);
    }
    if (z[r][c] === null || s.depth_mm[i] > z[r][c]) {
      z[r][c] = s.depth_mm[i];
      customdata[r][c][2] = p;
      customdata[r][c][3] = s.stiffness_loss_pct[i];
    }
  });
  return { x0: (c0 + 0.5) * width, dx: width, z, count, customdata };
}

function depthColorbar(narrow) {
  return narrow
    ? { title: { text: "Depth (mm)", side: "top" }, orientation: "h", thickness: 10, len: 1, x: 0.5, xanchor: "center", y: -0.18, yanchor: "top" }
    : { title: { text: "Depth (mm)" }, thickness: 14, len: 0.9 };
}

/** The merged overview: a dark frame layer under the coloured cells (two heatmap images). */
function cellTraces(s, labels, depthMax, narrow, metresPerPixel) {
  const cells = spotCells(s, labels.length, metresPerPixel);
  const text = cells.count.map((row) => row.map((k) => (k ? plural(k, "soft spot") : "")));
  return [
    {
      type: "heatmap", meta: "spot-frames", x0: cells.x0, dx: cells.dx, y: labels, z: cells.z.map((row) => row.map((v) => (v === null ? null : 1))),
      colorscale: [[0, "#1b1f24"], [1, "#1b1f24"]], showscale: false, hoverinfo: "skip", ygap: 2,
    },
    {
      type: "heatmap", meta: "spot-cells", name: "Soft spots", x0: cells.x0, dx: cells.dx, y: labels, z: cells.z, text, customdata: cells.customdata,
      colorscale: "Viridis", reversescale: true, zmin: 0, zmax: depthMax, xgap: 2, ygap: 4, hoverongaps: false,
      colorbar: depthColorbar(narrow),
      hovertemplate: "%{y}<br>%{text} in %{customdata[0]:.0f}–%{customdata[1]:.0f} m<br>deepest %{z:.2f} mm at %{customdata[2]:.0f} m, stiffness loss %{customdata[3]:.0f} %<extra></extra>",
    },
  ];
}

/**
 * The chainage map's traces. `metresPerPixel` is the drawn scale: the extent bars are drawn
 * only when a typical soft spot is at least a pixel long. Over a whole line (100 km on ~1 000
 * px, ~100 m per pixel) they would be thousands of invisible SVG paths, as costly to draw as
 * the markers themselves. More than `MAX_MARKERS` spots are drawn merged into cells.
 */
export function mapTraces(map, heat, narrow = false, metresPerPixel = 0, separated = []) {
  const labels = rowLabels(map.runs || [], narrow);
  const traces = [];
  if (map.heatmap) traces.push(heatmapTrace(map.heatmap, labels, heat));
  const s = map.spots || { run_index: [], start_m: [], end_m: [], peak_m: [], depth_mm: [], stiffness_loss_pct: [] };
  const n = s.peak_m.length;
  // one colour scale for the runs' spots and the separated ones (depth under 100 kN)
  const depthMax = Math.max(0.5, ...s.depth_mm, ...separated.map((d) => d.depth_mm));
  const sepTraces = separated.length ? separatedTraces(separated, narrow ? SEPARATED_ROW.narrow : SEPARATED_ROW.wide, depthMax, n ? null : depthColorbar(narrow)) : [];
  if (separated.length && traces.length) traces[0] = withEmptyRow(traces[0], sepTraces[0].y[0]);
  if (n > MAX_MARKERS && metresPerPixel > 0) {
    const cells = cellTraces(s, labels, depthMax, narrow, metresPerPixel);
    return traces.concat(separated.length ? cells.map((t) => withEmptyRow(t, sepTraces[0].y[0])) : cells, sepTraces);
  }
  if (n && medianExtent(s) >= metresPerPixel) {
    const segX = [];
    const segY = [];
    for (let i = 0; i < n; i += 1) {
      segX.push(s.start_m[i], s.end_m[i], null);
      const y = labels[s.run_index[i]];
      segY.push(y, y, null);
    }
    traces.push({
      type: "scatter", mode: "lines", name: "Extent", meta: "extents", x: segX, y: segY, hoverinfo: "skip", showlegend: false,
      line: { color: "#1b1f24", width: 3 },
    });
  }
  if (n) {
    traces.push({
      type: "scatter", mode: "markers", name: "Soft spots", meta: "spots",
      x: s.peak_m, y: s.run_index.map((i) => labels[i]),
      marker: {
        color: s.depth_mm, colorscale: "Viridis", reversescale: true, cmin: 0, cmax: depthMax,
        // Dense maps (drawn without a known scale) get smaller markers so that zones stay apart.
        size: s.depth_mm.map((d) => (n > MAX_MARKERS ? 5 + 8 * Math.min(d / depthMax, 1) : 8 + 14 * Math.min(d / depthMax, 1))),
        symbol: s.depth_mm.map((d) => CLASSES[severityClass(d)].symbol),
        line: { color: "#1b1f24", width: 1 },
        colorbar: depthColorbar(narrow),
      },
      customdata: s.peak_m.map((_, i) => [s.start_m[i], s.end_m[i], s.depth_mm[i], s.stiffness_loss_pct[i]]),
      hovertemplate: "%{y}<br>%{customdata[0]:.1f}–%{customdata[1]:.1f} m, depth %{customdata[2]:.2f} mm, stiffness loss %{customdata[3]:.0f} %<extra></extra>",
    });
  }
  return traces.concat(sepTraces);
}

/** A heatmap trace with an empty first row labelled `label`: plotly's heatmap on a category
 * axis expects a row of z (and of text and customdata) for every category of the axis, and
 * fails to draw ("reading 'length'") when the separated row has none. */
function withEmptyRow(trace, label) {
  const width = trace.z.length ? trace.z[0].length : 0;
  const empty = (v) => new Array(width).fill(v);
  const padded = { ...trace, y: [label, ...trace.y], z: [empty(null), ...trace.z] };
  if (trace.text) padded.text = [empty(""), ...trace.text];
  if (trace.customdata) padded.customdata = [empty(null), ...trace.customdata];
  return padded;
}

/** A loss with its band as words ("38 % (30–46 %)"; "—" when there is none). */
function lossText(d) {
  if (d.stiffness_loss_pct === null || d.stiffness_loss_pct === undefined) return "—";
  const band = d.stiffness_loss_lo_pct !== null && d.stiffness_loss_lo_pct !== undefined && d.stiffness_loss_hi_pct !== null && d.stiffness_loss_hi_pct !== undefined
    ? ` (${fmt(d.stiffness_loss_lo_pct, 0)}–${fmt(d.stiffness_loss_hi_pct, 0)} %)`
    : "";
  return `${fmt(d.stiffness_loss_pct, 0)} %${band}`;
}

/**
 * The separated soft spots' row: their extents as bars and a marker at the deepest point,
 * coloured, sized and shaped by their depth under a 100 kN wheel like the runs' spots
 * (`defects`: the register's defects of source "separated"; `depthMax` the shared scale, mm).
 * The markers carry the defect's rank (customdata[0]) so that a click can open it. `colorbar`:
 * the depth scale, given when no run's spots draw it (over rough rail no single pass has any).
 */
export function separatedTraces(defects, label, depthMax, colorbar = null) {
  const segX = [];
  const segY = [];
  defects.forEach((d) => { segX.push(d.start_m, d.end_m, null); segY.push(label, label, null); });
  return [
    {
      type: "scatter", mode: "lines", name: "Separated extent", meta: "separated-extents", x: segX, y: segY, hoverinfo: "skip", showlegend: false,
      line: { color: "#1b1f24", width: 3 },
    },
    {
      type: "scatter", mode: "markers", name: "Separated soft spots", meta: "separated",
      x: defects.map((d) => d.peak_m), y: defects.map(() => label),
      marker: {
        color: defects.map((d) => d.depth_mm), colorscale: "Viridis", reversescale: true, cmin: 0, cmax: depthMax,
        size: defects.map((d) => 8 + 14 * Math.min(d.depth_mm / depthMax, 1)),
        symbol: defects.map((d) => CLASSES[severityClass(d.depth_mm)].symbol),
        line: { color: "#1b1f24", width: 1 },
        ...(colorbar ? { colorbar } : {}),
      },
      customdata: defects.map((d) => [d.rank ?? null, d.start_m, d.end_m, d.depth_mm, lossText(d), d.evidence_text || "separated"]),
      hovertemplate: "%{y} (%{customdata[5]})<br>%{customdata[1]:.1f}–%{customdata[2]:.1f} m, depth %{customdata[3]:.2f} mm under 100 kN, stiffness loss %{customdata[4]}<br>click: its profile across runs<extra></extra>",
    },
  ];
}

/** Whether a plot is phone-narrow (< 560 px): shorter run labels, smaller margins and ticks,
 * the colour bar below the plot instead of beside it. */
export function isNarrow(div) {
  return div.clientWidth > 0 && div.clientWidth < 560;
}

export function mapLayout(labels, map, narrow = false) {
  const rowHeight = labels.length > 30 ? 14 : 34;
  return baseLayout({
    height: Math.min(900, Math.max(320, 140 + rowHeight * labels.length)) + (narrow ? 60 : 0),
    hovermode: "closest",
    showlegend: false,
    // Narrow: the margin grows with the (short) labels only (automargin), not a fixed 190 px.
    margin: narrow ? { l: 8, r: 8, t: 12, b: 100 } : { l: 190, r: 24, t: 16, b: 52 },
    xaxis: {
      title: { text: "Chainage (m)", standoff: 6 }, gridcolor: "#e3e6ea", zeroline: false, automargin: true,
      nticks: narrow ? 4 : undefined, tickfont: { size: narrow ? 10 : 12 },
      range: map.chainage_min_m !== null && map.chainage_min_m !== undefined ? [map.chainage_min_m, map.chainage_max_m] : undefined,
    },
    yaxis: { type: "category", categoryorder: "array", categoryarray: labels.slice().reverse(), automargin: true, gridcolor: "#eef0f3", fixedrange: true, tickfont: { size: narrow ? 10 : 12 } },
  });
}

/** Metres of chainage per pixel of the plot area for the x range [a, b] (m). */
function scaleOf(div, layout, [a, b]) {
  const width = Math.max(1, div.clientWidth - layout.margin.l - layout.margin.r);
  return (b - a) / width;
}

/** Run labels for the map's rows: the run's own label, else its date and id (short on a
 * phone). */
function rowLabels(runs, narrow) {
  const short = (iso) => (iso ? new Date(iso).toLocaleDateString(undefined, { month: "short", day: "numeric" }) : "");
  return runs.map((r) => (narrow ? `${short(r.recorded_at)} #${r.id}`.trim() : r.label || `${fmtDate(r.recorded_at)} · run ${r.id}`));
}

/**
 * Draw the chainage map card into `main`. `t0` is when the page started loading (the note
 * reports the load time). Returns {section, stop}: the card and the page's cleanup.
 */
export async function mapCard(main, { enc, map, t0, isStopped }) {
  const runs = map.runs || [];
  const mapDiv = h("div", { class: "plot plot-map", id: "chainage-map", role: "figure", "aria-label": "Chainage map of soft spots: chainage across, runs down, severity as colour, size and symbol" });
  const heatToggle = h("input", { type: "checkbox", id: "toggle-heatmap", checked: true });
  const mapNote = h("p", { class: "hint", id: "map-note" });
  const legend = legendBox();
  const mapSection = h("section", { class: "card", "aria-labelledby": "map-h" },
    h("div", { class: "section-head" },
      h("h2", { id: "map-h" }, "Chainage map"),
      h("label", { class: "check" }, heatToggle, " Profile level as background")),
    h("p", { class: "hint" }, "Each row is a run (newest at the top); a top row “Separated”, when there is one, holds the soft spots separated from the rail's geometry across wheel loads (over rough rail no single run sees them; click one for its profile across runs). Markers are soft spots at their deepest point; zoomed in far enough to see it, a bar shows their extent. Darker, larger and more angular markers are deeper. With too many to draw one by one (a long line), a run's spots are merged per few pixels of chainage into a framed cell coloured by the deepest (hover: how many, the deepest); zoom in to see each. Drag to zoom; the background is recomputed for the zoomed window."),
    mapDiv,
    legend,
    mapNote,
  );
  main.appendChild(mapSection);

  const narrow = isNarrow(mapDiv);
  const labels = rowLabels(runs, narrow);
  // the register's separated soft spots (they arrive after the map: `showSeparated`)
  let separated = [];
  let openZone = () => {};
  const rows = () => (separated.length ? [narrow ? SEPARATED_ROW.narrow : SEPARATED_ROW.wide, ...labels] : labels);
  const P = await loadPlotly();
  const layout = mapLayout(rows(), map, narrow);
  const fullRange = [map.chainage_min_m ?? 0, map.chainage_max_m ?? 0];
  await P.newPlot(mapDiv, mapTraces(map, heatToggle.checked, narrow, scaleOf(mapDiv, layout, fullRange)), layout, { ...CONFIG, scrollZoom: false });
  mapSection.insertBefore(zoomControls(mapDiv, { label: "Chainage map view" }), legend);
  const elapsed = performance.now() - t0;
  const describe = (m, prefix) => {
    mapNote.textContent = prefix
      + (m.heatmap ? `Background: lowest level per ${fmt(m.heatmap.bin_m, m.heatmap.bin_m < 10 ? 2 : 0)} m cell.` : `No background: ${m.heatmap_note || "no profile stored in this window"}.`)
      + (map.runs_omitted ? ` ${map.runs_omitted} older runs not shown.` : "")
      + (map.runs_pending ? ` ${plural(map.runs_pending, "run")} still processing or failed ${map.runs_pending === 1 ? "is" : "are"} not shown.` : "");
  };
  // "single-run": over rough rail no single run detects a soft support, the separation across
  // wheel loads does (the track page adds those from the register)
  describe(map, `${plural(map.spots ? map.spots.peak_m.length : 0, "single-run soft spot")} from ${plural(runs.length, "run")}, loaded in ${(elapsed / 1000).toFixed(2)} s. `);

  // Zooming asks the server for that window only: its soft spots and, up to 10 km wide, the
  // binned levels; the plot then holds what it shows rather than the whole line.
  let relayoutTimer = null;
  let requestSeq = 0;
  let current = map;
  let currentRange = null;
  const redraw = (m, range) => {
    current = m;
    currentRange = range;
    const lay = { ...mapLayout(rows(), map, narrow), xaxis: { ...layout.xaxis } };
    if (range) lay.xaxis = { ...lay.xaxis, range, autorange: false };
    return P.react(mapDiv, mapTraces(m, heatToggle.checked, narrow, scaleOf(mapDiv, lay, range || fullRange), separated), lay, { ...CONFIG, scrollZoom: false });
  };

  async function loadWindow(range) {
    const seq = ++requestSeq;
    if (range === "full") {
      if (current !== map) await redraw(map, null);
      describe(map, "Whole line. ");
      return;
    }
    const [a, b] = range;
    try {
      const part = await apiFetch(`/api/v1/views/tracks/${enc}/chainage-map?bins=1200&zones=false&heatmap=${heatToggle.checked}&from_m=${encodeURIComponent(a)}&to_m=${encodeURIComponent(b)}`);
      if (isStopped() || seq !== requestSeq) return;
      await redraw(part, [a, b]);
      describe(part, `${fmt(a, 0)}–${fmt(b, 0)} m: ${plural(part.spots.peak_m.length, "soft spot")}. `);
    } catch (err) {
      mapNote.textContent = `Cannot load this window: ${err.message}`;
    }
  }

  mapDiv.on("plotly_relayout", (ev) => {
    let range = null;
    if (ev["xaxis.range[0]"] !== undefined) range = [Number(ev["xaxis.range[0]"]), Number(ev["xaxis.range[1]"])];
    else if (Array.isArray(ev["xaxis.range"])) range = ev["xaxis.range"].map(Number);
    else if (ev["xaxis.autorange"]) range = "full";
    if (!range) return;
    clearTimeout(relayoutTimer);
    relayoutTimer = setTimeout(() => loadWindow(range), 150);
  });

  heatToggle.addEventListener("change", () => {
    const idx = mapDiv.data.findIndex((t) => t.meta === "heatmap");
    if (idx >= 0) P.restyle(mapDiv, { visible: heatToggle.checked }, [idx]);
    else if (heatToggle.checked) loadWindow(mapDiv.layout.xaxis.range.map(Number));
  });

  mapDiv.on("plotly_click", (ev) => {
    const pt = (ev.points || []).find((p) => p.data.meta === "separated");
    if (pt && separated[pt.pointIndex]) openZone(separated[pt.pointIndex]);
  });

  return {
    section: mapSection,
    stop: () => clearTimeout(relayoutTimer),
    /** Draw the register's separated soft spots (ranked defects of source "separated") in
     * the top row; a click on one calls `open(defect)`. */
    showSeparated(defects, open) {
      separated = defects;
      openZone = open;
      return separated.length ? redraw(current, currentRange) : Promise.resolve();
    },
  };
}
