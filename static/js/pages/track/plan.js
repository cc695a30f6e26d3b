// Plan view of a track's centerline (issue 11): the line in local metres (east, north; no map
// tiles), the register's defects marked at their chainage (click one to open it in the
// register), and the centerline upload (GeoJSON or CSV chainage_m,lat,lon).

import { h, clear, fmtKm, fmtKmRange, messageBox } from "../../dom.js";

const RUN_COLOURS = ["#0072b2", "#e69f00", "#009e73", "#cc79a7", "#56b4e9", "#d55e00"];
import { ApiError, apiFetch, apiGetOptional } from "../../api.js";
import { CONFIG, COLORS, plotly } from "../../plots.js";

/** Positions (m) of the chainages `c` on the line: linear along its vertices' chainage. */
export function pointsAt(plan, c) {
  const ch = plan.chainage_m;
  const out = { x: [], y: [] };
  for (const v of c) {
    if (v < ch[0] || v > ch[ch.length - 1]) { out.x.push(null); out.y.push(null); continue; }
    let lo = 0, hi = ch.length - 1;
    while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (ch[mid] <= v) lo = mid; else hi = mid; }
    const f = ch[hi] > ch[lo] ? (v - ch[lo]) / (ch[hi] - ch[lo]) : 0;
    out.x.push(plan.x_m[lo] + f * (plan.x_m[hi] - plan.x_m[lo]));
    out.y.push(plan.y_m[lo] + f * (plan.y_m[hi] - plan.y_m[lo]));
  }
  return out;
}

function contentType(file) {
  return /\.csv$/i.test(file.name) ? "text/csv" : "application/geo+json";
}

/**
 * The plan card: {section, showDefects(getZones, onZone)}. `showDefects` marks the ranked
 * defects on the plan; clicking a marker calls `onZone(zone)` (the register opens it).
 */
export function planCard(enc, { hasCenterline = true } = {}) {
  const plotDiv = h("div", { class: "plot plot-plan", id: "plan-plot", role: "figure", "aria-label": "Plan view of the track's centerline with chainage marks, the runs' stretches and the defects" });
  const info = h("p", { class: "hint", id: "plan-info" });
  const flag = h("p", { class: "message warning", id: "plan-flag", role: "status", hidden: true });
  const status = messageBox("info");
  const fileInput = h("input", { type: "file", id: "centerline-file", accept: ".geojson,.json,.csv,application/geo+json,application/json,text/csv" });
  const startInput = h("input", { type: "number", id: "centerline-start", step: "any", placeholder: "from the file, else 0" });
  const uploadBtn = h("button", { type: "button", class: "button secondary", id: "centerline-upload" }, "Upload centerline");
  const form = h("div", { class: "grid-3 centerline-form" },
    h("label", {}, "Centerline (GeoJSON LineString, or CSV chainage_m,lat,lon)", fileInput),
    h("label", {}, "Chainage of the first vertex (m, GeoJSON only)", startInput),
    h("div", {}, uploadBtn));
  const section = h("section", { class: "card", id: "plan-card", "aria-labelledby": "plan-h" },
    h("h2", { id: "plan-h" }, "Plan view"), info, flag, plotDiv, status.el,
    h("details", { id: "centerline-details" }, h("summary", {}, "Centerline of the track"), form));
  let plan = null;
  let zonesOf = () => [];
  let onZone = () => {};
  let runs = [];

  /** A centerline that covers none of the track's runs cannot place them: say so. */
  function checkCoverage() {
    flag.hidden = true;
    if (!plan || !runs.length) return;
    const ch = plan.chainage_m;
    const lo = ch[0], hi = ch[ch.length - 1];
    const covered = runs.filter((r) => r.chainage_min_m != null && r.chainage_max_m >= lo && r.chainage_min_m <= hi);
    if (!covered.length) {
      const rlo = Math.min(...runs.map((r) => r.chainage_min_m ?? Infinity));
      const rhi = Math.max(...runs.map((r) => r.chainage_max_m ?? -Infinity));
      flag.textContent = `This centerline (${fmtKmRange(lo, hi, 0)}) covers none of the track's runs (${fmtKmRange(rlo, rhi, 0)}): check its chainage of the first vertex, or that it is this track's line.`;
      flag.hidden = false;
    }
  }

  function draw() {
    if (!plan) return;
    const zones = zonesOf();
    const pts = pointsAt(plan, zones.map((z) => z.peak_m ?? 0.5 * (z.start_m + z.end_m)));
    const traces = [
      { type: "scatter", mode: "lines", x: plan.x_m, y: plan.y_m, name: "Centerline", line: { color: COLORS.fused, width: 2 },
        customdata: plan.chainage_m, hovertemplate: "chainage %{customdata:.1f} m<extra></extra>" },
      { type: "scatter", mode: "markers", x: pts.x, y: pts.y, name: "Defects", customdata: zones.map((z) => z.id),
        text: zones.map((z) => `defect ${z.id}: ${fmtKmRange(z.start_m, z.end_m)}, ${z.evidence_text || ""}`),
        hovertemplate: "%{text}<extra></extra>", marker: { color: COLORS.spotLine, size: 11, symbol: "diamond" } },
    ];
    // chainage marks in km+m, about eight along the line
    const ch = plan.chainage_m;
    const span = ch[ch.length - 1] - ch[0];
    const step = [10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000].find((v) => span / v <= 8) || 50000;
    const marks = [];
    for (let v = Math.ceil(ch[0] / step) * step; v <= ch[ch.length - 1]; v += step) marks.push(v);
    const mp = pointsAt(plan, marks);
    traces.push({ type: "scatter", mode: "markers+text", x: mp.x, y: mp.y, name: "Chainage (km+m)",
      text: marks.map((v) => fmtKm(v, 0)), textposition: "top right", textfont: { size: 10, color: "#374151" }, customdata: marks,
      marker: { color: "#374151", size: 5, symbol: "line-ns-open" }, hoverinfo: "skip" });
    // each run's placed stretch along the line, its start and end marked
    runs.slice(0, 12).forEach((r, i) => {
      const a = r.chainage_min_m, b = r.chainage_max_m;
      if (a == null || b == null) return;
      const inner = ch.filter((v) => v > a && v < b);
      const alongC = [a, ...inner, b];
      const along = pointsAt(plan, alongC);
      const ends = pointsAt(plan, [a, b]);
      const colour = RUN_COLOURS[i % RUN_COLOURS.length];
      traces.push({ type: "scatter", mode: "lines", x: along.x, y: along.y, name: `${r.label || `run ${r.id}`} (${fmtKmRange(a, b, 0)})`,
        line: { color: colour, width: 6 }, opacity: 0.45, hoverinfo: "name", legendgroup: `run-${r.id}`, customdata: alongC });
      traces.push({ type: "scatter", mode: "markers", x: ends.x, y: ends.y, showlegend: false, legendgroup: `run-${r.id}`,
        marker: { color: colour, size: 9, symbol: ["circle", "square"] }, customdata: [a, b], text: [`start of ${r.label || `run ${r.id}`}`, `end of ${r.label || `run ${r.id}`}`], hovertemplate: "%{text}<extra></extra>" });
    });
    const layout = {
      margin: { l: 64, r: 24, t: 16, b: 48 }, paper_bgcolor: "#ffffff", plot_bgcolor: "#ffffff", hovermode: "closest",
      showlegend: true, legend: { orientation: "h", x: 0, y: -0.15, yanchor: "top" },
      xaxis: { title: { text: "East (m)" }, gridcolor: "#e3e6ea", zeroline: false },
      yaxis: { title: { text: "North (m)" }, gridcolor: "#e3e6ea", zeroline: false, scaleanchor: "x", scaleratio: 1 },
    };
    const P = plotly();
    P.react(plotDiv, traces, layout, CONFIG).then(() => {
      if (plotDiv.removeAllListeners) plotDiv.removeAllListeners("plotly_click");
      plotDiv.on("plotly_click", (ev) => {
        const p = ev.points && ev.points[0];
        if (!p) return;
        // A click on a marker names its defect; on the line (the markers sit on it, so the
        // line's vertex can be the nearest point), the defect within 20 m of that chainage.
        const near = (c) => zonesOf().find((z) => c >= z.start_m - 20 && c <= z.end_m + 20);
        const zone = p.curveNumber === 1 ? zonesOf().find((z) => z.id === p.customdata) : near(p.customdata);
        if (!zone) return;
        onZone(zone);
        info.textContent = `Defect ${zone.id} (${fmtKmRange(zone.start_m, zone.end_m)}) is open in the register below.`;
      });
    });
  }

  // the track says whether it has a centerline: no request that is known to answer 404
  let known = hasCenterline;
  async function load() {
    try {
      plan = known ? await apiGetOptional(`/api/v1/tracks/${enc}/centerline/plan`) : null;
    } catch (err) {
      status.show(`Cannot load the centerline: ${err.message}`, "error");
      return;
    }
    if (!plan) {
      clear(plotDiv);
      plotDiv.hidden = true;
      info.textContent = "This track has no centerline: upload one to draw the line and to place runs by their GNSS fixes (no start chainage needed).";
      section.querySelector("#centerline-details").open = true;
      return;
    }
    plotDiv.hidden = false;
    const ch = plan.chainage_m;
    info.textContent = `Centerline ${fmtKmRange(ch[0], ch[ch.length - 1], 0)} (${ch.length} vertices), in metres east and north of its centre, with chainage marks and each run's stretch (start: circle, end: square). Click a defect to open it in the register.`;
    checkCoverage();
    draw();
  }

  uploadBtn.addEventListener("click", async () => {
    const file = fileInput.files && fileInput.files[0];
    if (!file) {
      status.show("Choose a GeoJSON or CSV file first.", "error");
      return;
    }
    const q = startInput.value !== "" ? `?start_chainage_m=${encodeURIComponent(startInput.value)}` : "";
    uploadBtn.disabled = true;
    try {
      const body = await file.text();
      const got = await apiFetch(`/api/v1/tracks/${enc}/centerline${q}`, {
        method: "PUT", headers: { "Content-Type": contentType(file), Accept: "application/json" }, body,
      });
      status.show(`Centerline stored: ${got.n_vertices} vertices, ${fmtKmRange(got.start_chainage_m, got.end_chainage_m)}.`, "success");
      known = true;
      await load();
    } catch (err) {
      status.show(err instanceof ApiError ? `The centerline was refused: ${err.message}` : err.message, "error");
    } finally {
      uploadBtn.disabled = false;
    }
  });

  load();
  return {
    section,
    showDefects(getZones, open) {
      zonesOf = getZones;
      onZone = open;
      draw();
    },
    /** The track's runs (id, label, aligned chainage_min_m/max_m): drawn and checked. */
    showRuns(list) {
      runs = list || [];
      checkCoverage();
      draw();
    },
  };
}
