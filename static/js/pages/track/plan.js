// Plan view of a track's centerline (issue 11): the line in local metres (east, north; no map
// tiles), the register's defects marked at their chainage (click one to open it in the
// register), and the centerline upload (GeoJSON or CSV chainage_m,lat,lon).

import { h, clear, fmt, messageBox } from "../../dom.js";
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
export function planCard(enc) {
  const plotDiv = h("div", { class: "plot plot-plan", id: "plan-plot", role: "img", "aria-label": "Plan view of the track's centerline with its defects" });
  const info = h("p", { class: "hint", id: "plan-info" });
  const status = messageBox("info");
  const fileInput = h("input", { type: "file", id: "centerline-file", accept: ".geojson,.json,.csv,application/geo+json,application/json,text/csv" });
  const startInput = h("input", { type: "number", id: "centerline-start", step: "any", placeholder: "from the file, else 0" });
  const uploadBtn = h("button", { type: "button", class: "button secondary", id: "centerline-upload" }, "Upload centerline");
  const form = h("div", { class: "grid-3 centerline-form" },
    h("label", {}, "Centerline (GeoJSON LineString, or CSV chainage_m,lat,lon)", fileInput),
    h("label", {}, "Chainage of the first vertex (m, GeoJSON only)", startInput),
    h("div", {}, uploadBtn));
  const section = h("section", { class: "card", id: "plan-card", "aria-labelledby": "plan-h" },
    h("h2", { id: "plan-h" }, "Plan view"), info, plotDiv, status.el,
    h("details", { id: "centerline-details" }, h("summary", {}, "Centerline of the track"), form));
  let plan = null;
  let zonesOf = () => [];
  let onZone = () => {};

  function draw() {
    if (!plan) return;
    const zones = zonesOf();
    const pts = pointsAt(plan, zones.map((z) => z.peak_m ?? 0.5 * (z.start_m + z.end_m)));
    const traces = [
      { type: "scatter", mode: "lines", x: plan.x_m, y: plan.y_m, name: "Centerline", line: { color: COLORS.fused, width: 2 },
        customdata: plan.chainage_m, hovertemplate: "chainage %{customdata:.1f} m<extra></extra>" },
      { type: "scatter", mode: "markers", x: pts.x, y: pts.y, name: "Defects", customdata: zones.map((z) => z.id),
        text: zones.map((z) => `defect ${z.id}: ${fmt(z.start_m, 1)}–${fmt(z.end_m, 1)} m, ${z.priority ?? z.status ?? ""}`),
        hovertemplate: "%{text}<extra></extra>", marker: { color: COLORS.spotLine, size: 11, symbol: "diamond" } },
    ];
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
        info.textContent = `Defect ${zone.id} (${fmt(zone.start_m, 1)}–${fmt(zone.end_m, 1)} m) is open in the register below.`;
      });
    });
  }

  async function load() {
    try {
      plan = await apiGetOptional(`/api/v1/tracks/${enc}/centerline/plan`);
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
    info.textContent = `Centerline ${fmt(ch[0], 0)}–${fmt(ch[ch.length - 1], 0)} m (${ch.length} vertices), in metres east and north of its centre. Click a defect to open it in the register.`;
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
      status.show(`Centerline stored: ${got.n_vertices} vertices, ${fmt(got.start_chainage_m, 1)}–${fmt(got.end_chainage_m, 1)} m.`, "success");
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
  };
}
