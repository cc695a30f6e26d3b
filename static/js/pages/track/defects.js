// The track page's defect register: the sortable table of tracked defects (most urgent first)
// and the profiles of all runs around the chosen defect.

import { h, clear, announce, fmt, fmtKm, fmtKmRange, plural, scrollTable } from "../../dom.js";
import { apiFetch, apiGetOptional } from "../../api.js";
import { baseLayout, CONFIG, loadPlotly, viridis } from "../../plots.js";
import { REGISTER_COLUMNS, aggregateTraces, defectShapes } from "../../register.js";
import { provisionalBanner, spotsAre } from "../../provisional.js";
import { interpAt } from "../../series.js";

/** Group index of each load (N): sorted, a load 10 % or more above its group's lightest
 * starts a new group (the separation's own threshold); unknown loads: group 0. */
function loadGroups(loads) {
  const known = loads.map((v, i) => [v, i]).filter(([v]) => v).sort((a, b) => a[0] - b[0]);
  const out = loads.map(() => 0);
  let g = 0;
  let base = known.length ? known[0][0] : 0;
  for (const [v, i] of known) {
    if (v >= 1.1 * base) {
      g += 1;
      base = v;
    }
    out[i] = g;
  }
  return out;
}

/** Each run's level minus the separated rail geometry (mm; null where either is missing):
 * what is left is the dip under that run's own wheel load, deeper under a heavier wheel
 * where the support is soft. */
export function minusGeometry(run, stiffness) {
  const gx = stiffness.chainage_m;
  const gy = stiffness.geometry_mm;
  return run.level_mm.map((v, i) => {
    const g = v === null ? null : interpAt(gx, gy, run.chainage_m[i]);
    return g === null ? null : v - g;
  });
}

/** Plotly axis ticks labelled in km+m over [from, to] m (about six of them). */
export function kmTicks(from, to) {
  const span = Math.max(to - from, 1);
  const step = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000].find((s) => span / s <= 6) || 100000;
  const tickvals = [];
  for (let v = Math.ceil(from / step) * step; v <= to; v += step) tickvals.push(v);
  return { tickvals, ticktext: tickvals.map((v) => fmtKm(v, step < 1 ? 1 : 0)) };
}

function escapeExtra(text) {
  // Plotly renders <extra> content as pseudo-HTML: keep user text literal.
  return String(text).replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;");
}

export function zoneTable(zones, onSelect, columns = REGISTER_COLUMNS) {
  const cols = columns.filter((c) => !c.optional || zones.some((z) => z[c.key] !== undefined && z[c.key] !== null));
  let sortKey = "rank";
  let sortDir = 1;
  const tbody = h("tbody", {});
  const headers = {};
  const headRow = h("tr", {});
  for (const c of cols) {
    const btn = h("button", { type: "button", class: "sort", title: c.title, onclick: () => sortBy(c.key) }, c.label);
    const th = h("th", { scope: "col", class: c.num ? "num" : "" }, btn);
    headers[c.key] = th;
    headRow.appendChild(th);
  }
  let selected = null;

  function sortBy(key) {
    if (sortKey === key) sortDir = -sortDir;
    else {
      sortKey = key;
      sortDir = ["depth_mm", "depth_max_mm", "stiffness_loss_pct", "runs_seen", "trend_mm_per_month", "trend_loss_pct_per_month"].includes(key) ? -1 : 1;
    }
    draw();
    announce(`Zones sorted by ${cols.find((c) => c.key === key).label}, ${sortDir > 0 ? "ascending" : "descending"}.`);
  }

  function draw() {
    const col = cols.find((c) => c.key === sortKey);
    const sorted = zones.slice().sort((a, b) => {
      const va = col.get(a);
      const vb = col.get(b);
      if (va === vb) return a.rank - b.rank;
      if (va === null || va === undefined) return 1;
      if (vb === null || vb === undefined) return -1;
      return (va < vb ? -1 : 1) * sortDir;
    });
    for (const [key, th] of Object.entries(headers)) {
      if (key === sortKey) th.setAttribute("aria-sort", sortDir > 0 ? "ascending" : "descending");
      else th.removeAttribute("aria-sort");
    }
    clear(tbody);
    for (const z of sorted) {
      const btn = h("button", {
        type: "button", class: "button small", // The name starts with the visible text (the rank), as speech input expects.
        "aria-label": `${z.rank}: show the profiles around zone ${fmt(z.start_m, 1)} to ${fmt(z.end_m, 1)} m`,
        onclick: () => {
          selected = z;
          for (const tr of tbody.querySelectorAll("tr")) tr.classList.remove("selected");
          row.classList.add("selected");
          onSelect(z);
        },
      }, String(z.rank));
      // The rank is the row's button (its profile across runs): one column fewer to fit 1366 px.
      const row = h("tr", { class: z === selected ? "selected" : "", "data-zone": String(z.rank) },
        cols.map((c) => (c.key === "rank"
          ? h("th", { scope: "row", class: "num" }, btn)
          : h("td", { class: [c.num ? "num" : "", c.cls ? c.cls(z) : ""].join(" ").trim() || null }, c.show ? c.show(z) : String(c.get(z) ?? "—")))));
      row.addEventListener("click", (e) => {
        if (e.target.closest("button")) return;
        btn.click();
      });
      tbody.appendChild(row);
    }
  }
  draw();
  const table = h("table", { class: "data sortable", id: "zone-table" },
    h("caption", { class: "visually-hidden" }, "Defect register, most urgent first; column titles sort the table"),
    h("thead", {}, headRow), tbody);
  return scrollTable("Defect register", table, "zone-table-wrap");
}

/**
 * The register card and the "defect across runs" card, appended to `main`. `getZones` gives
 * the current ranked defects. Returns {draw (redraw the table), showZone, select (show and
 * scroll to the plot)}.
 */
export function registerCards(main, { enc, getZones, isStopped }) {
  const zonePlotDiv = h("div", { class: "plot plot-zone", id: "zone-plot", role: "figure", "aria-label": "Profiles of all runs around the selected zone" });
  const zoneInfo = h("p", { class: "hint", id: "zone-info" }, "Choose a zone in the table to see its profile across runs.");
  // A separated defect hides in the rail's geometry on the loaded profiles: with the separated
  // geometry taken off, each pass's dip under its own load shows (on by default there).
  const minusToggle = h("input", { type: "checkbox", id: "zone-minus-geometry", checked: true });
  const minusLabel = h("label", { class: "check", hidden: true }, minusToggle, " Minus the separated rail geometry (each pass's dip under its own wheel load)");
  let shownZone = null;
  minusToggle.addEventListener("change", () => { if (shownZone) showZone(shownZone); });
  const onSelect = (zone) => {
    showZone(zone);
    zonePlotDiv.scrollIntoView({ behavior: "smooth", block: "nearest" });
  };
  const tableBox = h("div", { id: "register-box" });
  const draw = () => {
    const zones = getZones();
    clear(tableBox);
    const doubt = provisionalBanner(zones, spotsAre, "register-provisional");
    if (doubt) tableBox.appendChild(doubt);
    tableBox.appendChild(zones.length
      ? zoneTable(zones, onSelect)
      : h("p", { class: "muted", id: "register-empty" }, "No defect: no run found a soft spot on this track."));
  };
  draw();
  // The register has many columns: it and its plot take the full width, one above the other.
  main.appendChild(h("div", { class: "track-register" },
    h("section", { class: "card", "aria-labelledby": "zones-h" },
      h("h2", { id: "zones-h" }, "Defect register"),
      h("p", { class: "hint" }, "Soft spots of all aligned runs (of every run, as logged, when none is aligned) merged into tracked defects, most urgent first (priority from the limits below, then depth). Evidence: what supports it — single passes, or the separation of geometry from stiffness across passes of different wheel loads (“separated: 4 passes, 2 loads”). Depth and loss: the most trusted evidence, latest (a separated spot: its depth under a 100 kN wheel, its loss with the band). Trend: least-squares change per month. Status: new (one pass), confirmed (independent passes), worsening (significant growth) or stable. Chainage in km+m. Click a column title to sort; click a defect (or its rank) to see its profile across runs."),
      tableBox),
    h("section", { class: "card", "aria-labelledby": "zoneplot-h" },
      h("h2", { id: "zoneplot-h" }, "Defect across runs"),
      minusLabel,
      zoneInfo,
      zonePlotDiv),
  ));

  async function showZone(zone) {
    shownZone = zone;
    const width = Math.max(zone.end_m - zone.start_m, 2);
    const from = zone.start_m - Math.max(20, 2 * width);
    const to = zone.end_m + Math.max(20, 2 * width);
    const separated = zone.source === "separated";
    minusLabel.hidden = !separated;
    zoneInfo.textContent = `Loading the profiles of ${fmtKmRange(from, to, 0)}…`;
    try {
      const [win, aggWindow, stiff] = await Promise.all([
        apiFetch(`/api/v1/views/tracks/${enc}/window?from_m=${from}&to_m=${to}`),
        apiGetOptional(`/api/v1/tracks/${enc}/profile?from_m=${from}&to_m=${to}`).catch(() => null),
        separated && minusToggle.checked
          ? apiGetOptional(`/api/v1/tracks/${enc}/stiffness?from_m=${from}&to_m=${to}`).catch(() => null)
          : null,
      ]);
      if (isStopped() || shownZone !== zone) return;
      const minus = !!(stiff && Array.isArray(stiff.geometry_mm) && stiff.geometry_mm.some((v) => v !== null));
      const traces = [];
      const wr = win.runs || [];
      // The wheel load tells weak support from geometry: a soft spot deepens under the heavier
      // wheel, a geometric dip does not. Each load group gets its own dash (colour: date).
      const groups = loadGroups(wr.map((r) => r.wheel_load_n));
      const dashes = ["solid", "dash", "dot", "dashdot"];
      wr.forEach((r, i) => {
        const kn = r.wheel_load_n ? `${fmt(r.wheel_load_n / 1000, 0)} kN` : "load unknown";
        const name = `${r.label || `run ${r.id}`} · ${kn}`;
        traces.push({
          type: "scatter", mode: "lines", name,
          x: r.chainage_m, y: minus ? minusGeometry(r, stiff) : r.level_mm, meta: `run-${r.id}`,
          line: { color: viridis(wr.length > 1 ? i / (wr.length - 1) : 0), width: 1.3, dash: dashes[groups[i] % dashes.length] },
          hovertemplate: `%{y:.3f} mm<extra>${escapeExtra(name)}</extra>`,
        });
      });
      // the aggregate is a loaded profile: beside the dips it would read as one more of them
      if (!minus) traces.push(...aggregateTraces(aggWindow));
      const narrow = zonePlotDiv.clientWidth > 0 && zonePlotDiv.clientWidth < 560;
      const layout = baseLayout({
        height: narrow ? 380 + 18 * Math.min(traces.length, 12) : 380,
        shapes: defectShapes([zone]),
        xaxis: { title: { text: "Chainage (km+m)" }, range: [from, to], gridcolor: "#e3e6ea", ...kmTicks(from, to) },
        yaxis: { title: { text: minus ? "Level minus geometry (mm)" : "Loaded level (mm)" }, showgrid: true, gridcolor: "#e3e6ea", zerolinecolor: "#9aa3ad", automargin: true },
        // On a phone the legend goes below the plot, which keeps the width.
        legend: narrow ? { orientation: "h", x: 0, y: -0.25, yanchor: "top", font: { size: 10 } } : { orientation: "v", x: 1.02, y: 1, font: { size: 11 } },
        margin: narrow ? { l: 52, r: 8, t: 24, b: 60 } : { l: 64, r: 12, t: 24, b: 52 },
      });
      await (await loadPlotly()).react(zonePlotDiv, traces, layout, CONFIG);
      const covers = wr.length === 1 ? "1 run covers it" : `${wr.length} runs cover it`;
      const nLoads = new Set(groups).size;
      zoneInfo.textContent = `Zone ${fmtKmRange(zone.start_m, zone.end_m)} (shaded): ${covers}; evidence: ${zone.evidence_text || `${zone.runs_seen} detected a soft spot there`}.`
        + (wr.length > 1 ? " Lines run from dark (oldest) to light (newest)" : "")
        + (nLoads > 1 ? `; ${nLoads} wheel loads, one dash each (solid: the lightest), named in the legend.` : wr.length > 1 ? "." : "")
        + (minus ? " Drawn minus the separated rail geometry: each line is that pass's dip under its own wheel load, deeper under the heavier wheels where the support is soft." : "")
        + (separated && minusToggle.checked && !minus ? " The separated geometry is not available here: the loaded levels are drawn." : "");
      announce(`Showing zone at ${fmtKm(zone.peak_m)} across ${plural(wr.length, "run")}.`);
    } catch (err) {
      zoneInfo.textContent = `Cannot load the zone's profiles: ${err.message}`;
    }
  }

  return { draw, showZone, select: onSelect };
}
