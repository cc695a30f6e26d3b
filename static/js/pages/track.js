// Track view (the chainage map): every run of a track along chainage, soft spots as a map
// (x chainage, y run, colour + size + symbol = severity), the defect register (runs aligned,
// soft spots merged into tracked defects with status, trend and priority) and the profiles of
// all runs around a chosen defect, the aggregated profile, alerts since a date, the track's
// limits and exports. The register is the only zone model: a track whose runs were never
// aligned gets it too, over its runs as logged.

import { h, clear, append, announce, fmt, fmtDate, messageBox } from "../dom.js";
import { ApiError, apiFetch, apiGetOptional } from "../api.js";
import { CONFIG, baseLayout, plotly, viridis, zoomControls } from "../plots.js";
import {
  REGISTER_COLUMNS, aggregateCard, aggregateTraces, alertsCard, alignmentNotice, defectShapes,
  exportLinks, limitsCard,
} from "../register.js";
import { stiffnessCard } from "../stiffness.js";

// Severity classes by depth (mm): the symbol and size repeat what the colour says, so the map
// reads without colour vision.
const CLASSES = [
  { max: 0.15, symbol: "circle", label: "< 0.15 mm" },
  { max: 0.3, symbol: "square", label: "0.15–0.3 mm" },
  { max: 0.5, symbol: "diamond", label: "0.3–0.5 mm" },
  { max: Infinity, symbol: "x", label: "≥ 0.5 mm" },
];

function severityClass(depth) {
  return CLASSES.findIndex((c) => depth < c.max);
}

/**
 * The id of the track a route names (#/tracks/{id} or #/tracks/{name}). API calls use the id:
 * a name may hold "/" or other characters that do not survive a URL path.
 */
async function resolveTrack(ref) {
  const tracks = (await apiFetch("tracks?limit=1000")).data;
  const byId = /^\d+$/.test(ref) ? tracks.find((t) => String(t.id) === ref) : null;
  return byId || tracks.find((t) => t.name === ref) || null;
}

export async function render(main, [ref]) {
  let stopped = false;
  const heading = h("h1", { id: "track-title" }, "Track ", h("span", { class: "track-name" }, ref));
  const lead = h("p", { class: "lead", id: "track-lead" });
  const status = messageBox("info");
  main.append(heading, lead, status.el);

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
  const t0 = performance.now();
  // The map, the register (aligned runs; every run when none is aligned) and the track's runs
  // are asked for at once: the register is computed while the map travels.
  const mapP = apiFetch(`/api/v1/views/tracks/${enc}/chainage-map?bins=1200&zones=false`);
  const registerP = Promise.all([
    apiGetOptional(`/api/v1/tracks/${enc}/defects`),
    apiFetch(`/api/v1/runs?track=${enc}&limit=1000`).catch(() => null),
  ]);
  registerP.catch(() => {}); // awaited below; no unhandled rejection while the map loads
  let map;
  try {
    map = await mapP;
  } catch (err) {
    status.show(err instanceof ApiError && err.status === 404 ? `There is no track “${name}”.` : `Cannot load the chainage map: ${err.message}`, "error");
    return null;
  }
  let register = [];
  let trackRuns = [];
  try {
    const [defects, runList] = await registerP;
    trackRuns = runList ? runList.data : [];
    if (defects) register = defects;
  } catch (err) {
    status.show(`Cannot load the defect register: ${err.message}`, "error");
  }
  // The aggregated profile is made of aligned runs only: no card for a track without any.
  const anyAligned = trackRuns.some((r) => r.alignment && r.alignment.status !== "unaligned");

  const runs = map.runs || [];
  const doneRuns = runs; // the map shows processed runs only
  const trackInfo = map.track || {};
  append(lead, [
    `${doneRuns.length} processed run${doneRuns.length === 1 ? "" : "s"}`,
    map.chainage_min_m !== null && map.chainage_min_m !== undefined ? ` covering ${fmt(map.chainage_min_m, 0)}–${fmt(map.chainage_max_m, 0)} m` : "",
    trackInfo.description ? ` · ${trackInfo.description}` : "",
    " · ",
    h("a", { href: "#/upload" }, "Upload another run"),
  ]);
  if (runs.length === 0) {
    main.appendChild(h("p", { class: "muted" }, "No runs on this track yet."));
    return null;
  }
  main.appendChild(exportLinks(enc, track.id));
  const notice = alignmentNotice(trackRuns);
  if (notice) main.appendChild(notice);

  // ---- chainage map --------------------------------------------------------------------------
  const mapDiv = h("div", { class: "plot plot-map", id: "chainage-map", role: "img", "aria-label": "Chainage map of soft spots: chainage across, runs down, severity as colour, size and symbol" });
  const heatToggle = h("input", { type: "checkbox", id: "toggle-heatmap", checked: true });
  const mapNote = h("p", { class: "hint", id: "map-note" });
  const mapSection = h("section", { class: "card", "aria-labelledby": "map-h" },
    h("div", { class: "section-head" },
      h("h2", { id: "map-h" }, "Chainage map"),
      h("label", { class: "check" }, heatToggle, " Profile level as background")),
    h("p", { class: "hint" }, "Each row is a run (newest at the top). Markers are soft spots at their deepest point; the bar shows their extent. Darker, larger and more angular markers are deeper. Drag to zoom; the background is recomputed for the zoomed window."),
    mapDiv,
    legendBox(),
    mapNote,
  );
  main.appendChild(mapSection);

  const labels = runs.map((r) => r.label || `${fmtDate(r.recorded_at)} · run ${r.id}`);
  const P = plotly();
  const layout = mapLayout(labels, map);
  await P.newPlot(mapDiv, mapTraces(map, heatToggle.checked), layout, { ...CONFIG, scrollZoom: false });
  mapSection.insertBefore(zoomControls(mapDiv, { label: "Chainage map view" }), legendBoxOf(mapSection));
  const elapsed = performance.now() - t0;
  const describe = (m, prefix) => {
    mapNote.textContent = prefix
      + (m.heatmap ? `Background: lowest level per ${fmt(m.heatmap.bin_m, m.heatmap.bin_m < 10 ? 2 : 0)} m cell.` : `No background: ${m.heatmap_note || "no profile stored in this window"}.`)
      + (map.runs_omitted ? ` ${map.runs_omitted} older runs not shown.` : "")
      + (map.runs_pending ? ` ${map.runs_pending} runs still processing or failed are not shown.` : "");
  };
  describe(map, `${(map.spots ? map.spots.peak_m.length : 0).toLocaleString()} soft spots from ${runs.length} runs, loaded in ${(elapsed / 1000).toFixed(2)} s. `);

  // Zooming asks the server for that window only: its soft spots and, up to 10 km wide, the
  // binned levels; the plot then holds what it shows rather than the whole line.
  let relayoutTimer = null;
  let requestSeq = 0;
  let current = map;
  const redraw = (m, range) => {
    current = m;
    const lay = { ...mapLayout(labels, map), xaxis: { ...layout.xaxis } };
    if (range) lay.xaxis = { ...lay.xaxis, range, autorange: false };
    return P.react(mapDiv, mapTraces(m, heatToggle.checked), lay, { ...CONFIG, scrollZoom: false });
  };
  mapDiv.on("plotly_relayout", (ev) => {
    let range = null;
    if (ev["xaxis.range[0]"] !== undefined) range = [Number(ev["xaxis.range[0]"]), Number(ev["xaxis.range[1]"])];
    else if (Array.isArray(ev["xaxis.range"])) range = ev["xaxis.range"].map(Number);
    else if (ev["xaxis.autorange"]) range = "full";
    if (!range) return;
    clearTimeout(relayoutTimer);
    relayoutTimer = setTimeout(() => loadWindow(range), 150);
  });

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
      if (stopped || seq !== requestSeq) return;
      await redraw(part, [a, b]);
      describe(part, `${fmt(a, 0)}–${fmt(b, 0)} m: ${part.spots.peak_m.length.toLocaleString()} soft spots. `);
    } catch (err) {
      mapNote.textContent = `Cannot load this window: ${err.message}`;
    }
  }

  heatToggle.addEventListener("change", () => {
    const idx = mapDiv.data.findIndex((t) => t.meta === "heatmap");
    if (idx >= 0) P.restyle(mapDiv, { visible: heatToggle.checked }, [idx]);
    else if (heatToggle.checked) loadWindow(mapDiv.layout.xaxis.range.map(Number));
  });

  // ---- aggregated profile ---------------------------------------------------------------------
  let zones = ranked(register);
  const aggregate = anyAligned ? await aggregateCard(enc, () => zones) : null;
  if (aggregate) main.appendChild(aggregate.section);
  // Stiffness separated from rail geometry across passes of different wheel loads (issue 10).
  const stiffness = anyAligned ? stiffnessCard(enc) : null;
  if (stiffness) {
    main.appendChild(stiffness.section);
    stiffness.render();
  }

  // ---- register ------------------------------------------------------------------------------
  // The register comes ranked by priority.
  const zonePlotDiv = h("div", { class: "plot plot-zone", id: "zone-plot", role: "img", "aria-label": "Profiles of all runs around the selected zone" });
  const zoneInfo = h("p", { class: "hint", id: "zone-info" }, "Choose a zone in the table to see its profile across runs.");
  const onSelect = (zone) => {
    showZone(zone);
    zonePlotDiv.scrollIntoView({ behavior: "smooth", block: "nearest" });
  };
  const tableBox = h("div", { id: "register-box" });
  const drawTable = () => {
    clear(tableBox);
    tableBox.appendChild(zones.length
      ? zoneTable(zones, onSelect)
      : h("p", { class: "muted", id: "register-empty" }, "No defect: no run found a soft spot on this track."));
  };
  drawTable();
  // The register has many columns: it and its plot take the full width, one above the other.
  main.appendChild(h("div", { class: "track-register" },
    h("section", { class: "card", "aria-labelledby": "zones-h" },
      h("h2", { id: "zones-h" }, "Defect register"),
      h("p", { class: "hint" }, "Soft spots of all aligned runs (of every run, as logged, when none is aligned) merged into tracked defects, most urgent first (priority from the limits below, then depth). Seen: runs that detected it, of the runs covering it. Depth and loss: latest run. Trend: least-squares change per month. Status: new (one run), confirmed (two), worsening (significant growth) or stable. Click a column title to sort; click a defect (or its rank) to see its profile across runs."),
      tableBox),
    h("section", { class: "card", "aria-labelledby": "zoneplot-h" },
      h("h2", { id: "zoneplot-h" }, "Defect across runs"),
      zoneInfo,
      zonePlotDiv),
  ));

  // ---- alerts and limits ---------------------------------------------------------------------
  // Alerts and limits serve the maintenance of aligned tracks (a track whose runs were never
  // aligned has its register as logged, but nothing to plan from yet).
  if (anyAligned) {
    const alerts = alertsCard(enc);
    const limits = limitsCard(enc, async () => {
      register = await apiFetch(`/api/v1/tracks/${enc}/defects`);
      zones = ranked(register);
      drawTable();
      if (aggregate) await aggregate.render();
      if (stiffness) await stiffness.render();
      await alerts.load();
    });
    main.appendChild(h("div", { class: "track-lower" }, alerts.section, limits.section));
    limits.load();
    alerts.load();
  }

  async function showZone(zone) {
    const width = Math.max(zone.end_m - zone.start_m, 2);
    const from = zone.start_m - Math.max(20, 2 * width);
    const to = zone.end_m + Math.max(20, 2 * width);
    zoneInfo.textContent = `Loading the profiles of ${fmt(from, 0)}–${fmt(to, 0)} m…`;
    try {
      const [win, aggWindow] = await Promise.all([
        apiFetch(`/api/v1/views/tracks/${enc}/window?from_m=${from}&to_m=${to}`),
        apiGetOptional(`/api/v1/tracks/${enc}/profile?from_m=${from}&to_m=${to}`).catch(() => null),
      ]);
      if (stopped) return;
      const traces = [];
      const wr = win.runs || [];
      wr.forEach((r, i) => {
        traces.push({
          type: "scatter", mode: "lines", name: r.label || `run ${r.id}`,
          x: r.chainage_m, y: r.level_mm, meta: `run-${r.id}`,
          line: { color: viridis(wr.length > 1 ? i / (wr.length - 1) : 0), width: 1.3 },
          hovertemplate: `%{y:.3f} mm<extra>${escapeExtra(r.label || `run ${r.id}`)}</extra>`,
        });
      });
      traces.push(...aggregateTraces(aggWindow));
      const layout = baseLayout({
        height: 380,
        shapes: defectShapes([zone]),
        xaxis: { title: { text: "Chainage (m)" }, range: [from, to], gridcolor: "#e3e6ea" },
        legend: { orientation: "v", x: 1.02, y: 1, font: { size: 11 } },
        margin: { l: 64, r: 12, t: 24, b: 52 },
      });
      await P.react(zonePlotDiv, traces, layout, CONFIG);
      const covers = wr.length === 1 ? "1 run covers it" : `${wr.length} runs cover it`;
      zoneInfo.textContent = `Zone ${fmt(zone.start_m, 1)}–${fmt(zone.end_m, 1)} m (shaded): ${covers}, ${zone.runs_seen} detected a soft spot there.`
        + (wr.length > 1 ? " Lines run from dark (oldest) to light (newest)." : "");
      announce(`Showing zone at ${fmt(zone.peak_m, 1)} m across ${wr.length} runs.`);
    } catch (err) {
      zoneInfo.textContent = `Cannot load the zone's profiles: ${err.message}`;
    }
  }

  if (zones.length) showZone(zones[0]);
  if (aggregate) aggregate.render();
  announce(`Track ${name}: ${runs.length} runs, ${zones.length} zones.`);
  return () => {
    stopped = true;
    clearTimeout(relayoutTimer);
  };
}

function escapeExtra(text) {
  // Plotly renders <extra> content as pseudo-HTML: keep user text literal.
  return String(text).replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;");
}

function legendBoxOf(section) {
  return section.querySelector(".severity-legend");
}

function legendBox() {
  return h("ul", { class: "severity-legend", "aria-label": "Severity classes by depth" },
    CLASSES.map((c, i) => h("li", {}, h("span", { class: `sym sym-${c.symbol}`, "aria-hidden": "true", style: `--c:${viridis(1 - (i + 0.5) / CLASSES.length)}` }), c.label)));
}

function runLabels(m) {
  return (m.runs || []).map((r) => r.label || `run ${r.id}`);
}

function heatmapTrace(heat, labels, visible) {
  return {
    type: "heatmap", meta: "heatmap", name: "Level", x: heat.x, y: labels, z: heat.z,
    colorscale: [[0, "#4b5563"], [0.5, "#d1d5db"], [1, "#f9fafb"]],
    zmid: 0, showscale: false, visible, hoverongaps: false,
    hovertemplate: "%{x:.0f} m · %{y}<br>lowest level %{z:.2f} mm<extra></extra>",
  };
}

function mapTraces(map, heat) {
  const labels = runLabels(map);
  const traces = [];
  if (map.heatmap) traces.push(heatmapTrace(map.heatmap, labels, heat));
  const s = map.spots || { run_index: [], start_m: [], end_m: [], peak_m: [], depth_mm: [], stiffness_loss_pct: [] };
  const n = s.peak_m.length;
  if (n) {
    const segX = [];
    const segY = [];
    for (let i = 0; i < n; i += 1) {
      segX.push(s.start_m[i], s.end_m[i], null);
      const y = labels[s.run_index[i]];
      segY.push(y, y, null);
    }
    traces.push({
      type: "scatter", mode: "lines", name: "Extent", x: segX, y: segY, hoverinfo: "skip", showlegend: false,
      line: { color: "#1b1f24", width: 3 },
    });
    const depthMax = Math.max(0.5, ...s.depth_mm);
    traces.push({
      type: "scatter", mode: "markers", name: "Soft spots", meta: "spots",
      x: s.peak_m, y: s.run_index.map((i) => labels[i]),
      marker: {
        color: s.depth_mm, colorscale: "Viridis", reversescale: true, cmin: 0, cmax: depthMax,
        // Dense overviews (a whole line) get smaller markers so that zones stay apart.
        size: s.depth_mm.map((d) => (n > 1500 ? 5 + 8 * Math.min(d / depthMax, 1) : 8 + 14 * Math.min(d / depthMax, 1))),
        symbol: s.depth_mm.map((d) => CLASSES[severityClass(d)].symbol),
        line: { color: "#1b1f24", width: 1 },
        colorbar: { title: { text: "Depth (mm)" }, thickness: 14, len: 0.9 },
      },
      customdata: s.peak_m.map((_, i) => [s.start_m[i], s.end_m[i], s.depth_mm[i], s.stiffness_loss_pct[i]]),
      hovertemplate: "%{y}<br>%{customdata[0]:.1f}–%{customdata[1]:.1f} m, depth %{customdata[2]:.2f} mm, stiffness −%{customdata[3]:.0f} %<extra></extra>",
    });
  }
  return traces;
}

function mapLayout(labels, map) {
  const rowHeight = labels.length > 30 ? 14 : 34;
  return baseLayout({
    height: Math.min(900, Math.max(320, 140 + rowHeight * labels.length)),
    hovermode: "closest",
    showlegend: false,
    margin: { l: 190, r: 24, t: 16, b: 52 },
    xaxis: {
      title: { text: "Chainage (m)" }, gridcolor: "#e3e6ea", zeroline: false,
      range: map.chainage_min_m !== null && map.chainage_min_m !== undefined ? [map.chainage_min_m, map.chainage_max_m] : undefined,
    },
    yaxis: { type: "category", categoryorder: "array", categoryarray: labels.slice().reverse(), automargin: true, gridcolor: "#eef0f3", fixedrange: true },
  });
}

/** The register's defects with their rank (the register comes most urgent first). */
function ranked(defects) {
  return defects.map((d, i) => ({ ...d, rank: i + 1 }));
}

function zoneTable(zones, onSelect, columns = REGISTER_COLUMNS) {
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
        type: "button", class: "button small", "aria-label": `Show the profiles around zone ${fmt(z.start_m, 1)} to ${fmt(z.end_m, 1)} m`,
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
  return h("div", { class: "table-scroll zone-table-wrap" },
    h("table", { class: "data sortable", id: "zone-table" },
      h("caption", { class: "visually-hidden" }, "Defect register, most urgent first; column titles sort the table"),
      h("thead", {}, headRow), tbody));
}
