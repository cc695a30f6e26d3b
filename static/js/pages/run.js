// Run view: fused loaded profile with shaded, labelled soft spots; front/rear axle profiles on
// demand; raw signals against time; metadata and quality; downloads.

import { h, clear, append, announce, fmt, fmtDate, fmtKm, downloadBlob, messageBox, plural, scrollTable } from "../dom.js";
import { ApiError, apiFetch, apiGetOptional, runErrorMessage } from "../api.js";
import { baseLayout, COLORS, CONFIG, loadPlotly, softSpotLabels, softSpotShapes, TERMS, zoomControls, zoomTo } from "../plots.js";
import { unseenText } from "../visibility.js";
import { interpAt } from "../series.js";

const META_FIELDS = [
  ["recorded_at", "Recorded", (v) => fmtDate(v)],
  ["created_at", "Uploaded", (v) => fmtDate(v)],
  ["start_chainage_m", "Start chainage", (v) => `${fmt(v, 2)} m`],
  ["chainage_offset_m", "Alignment offset", (v) => `${fmt(v, 2)} m`],
  ["direction", "Direction", (v) => v],
  ["sample_rate_hz", "Sample rate", (v) => `${fmt(v, 0)} Hz`],
  ["n_samples", "Samples", (v) => Number(v).toLocaleString()],
  ["duration_s", "Duration", (v) => `${fmt(v, 1)} s`],
  ["speed_min_mps", "Speed min", (v) => `${fmt(v, 1)} m/s (${fmt(v * 3.6, 0)} km/h)`],
  ["speed_max_mps", "Speed max", (v) => `${fmt(v, 1)} m/s (${fmt(v * 3.6, 0)} km/h)`],
  ["chainage_min_m", "Chainage from", (v) => `${fmt(v, 1)} m`],
  ["chainage_max_m", "Chainage to", (v) => `${fmt(v, 1)} m`],
  ["method", "Inversion method", (v) => v],
  ["original_filename", "File", (v) => v],
  ["content_hash", "Content hash", (v) => String(v).slice(0, 16)],
];

const MAX_POINTS = 4000;

const QUALITY_FIELDS = {
  noise_accel_mps2: ["Accelerometer noise", "m/s² RMS", 4, "White-noise level estimated from the log."],
  noise_pitch_rate_radps: ["Gyroscope noise", "rad/s RMS", 6, "White-noise level estimated from the log."],
  axle_agreement_mm: ["Front/rear agreement", "mm RMS", 3, "RMS difference of the two axles' profiles: small means consistent."],
  coverage_m: ["Coverage", "m", 1, "Length of track covered by the fused profile."],
  speed_min_mps: ["Speed min", "m/s", 1, ""],
  speed_max_mps: ["Speed max", "m/s", 1, ""],
  sample_rate_hz: ["Sample rate", "Hz", 0, ""],
};

export async function render(main, [id]) {
  let stopped = false;
  let timer = null;
  const encId = encodeURIComponent(id);

  const heading = h("h1", {}, `Run ${id}`);
  const subtitle = h("p", { class: "lead", id: "run-subtitle" });
  const status = messageBox("info");
  main.append(heading, subtitle, status.el);

  // The chart's data is asked for with the run, not after it: on a cold first visit both are
  // in flight before plotly.js's evaluation holds the main thread, and the chart waits for the
  // longest of them (docs/benchmarks.md, issue 14). Unused while the run is not processed
  // (their 409 answers are ignored then).
  const chartData = Promise.all([
    apiFetch(`/api/v1/views/runs/${encId}/profile?max_points=${MAX_POINTS}`),
    apiFetch(`runs/${encId}/soft-spots`),
  ]);
  chartData.catch(() => {});
  let run;
  try {
    run = await apiFetch(`runs/${encId}`);
  } catch (err) {
    status.show(err instanceof ApiError && err.status === 404 ? `There is no run ${id}.` : `Cannot load run ${id}: ${err.message}`, "error");
    return null;
  }

  const track = run.track;
  append(subtitle, [
    "Track ", h("a", { href: `#/tracks/${encodeURIComponent(run.track_id)}`, id: "run-track-link" }, track),
    " · vehicle ", h("a", { href: `#/vehicles/${encodeURIComponent(run.vehicle)}`, id: "run-vehicle-link" }, run.vehicle),
    run.vehicle_version ? ` (parameters version ${run.vehicle_version})` : "",
    run.recorded_at ? ` · recorded ${fmtDate(run.recorded_at)}` : "",
  ]);

  if (run.status === "processing" || run.status === "queued" || run.status === "pending") {
    const bar = h("progress", { max: "1", "aria-label": "Processing progress" });
    status.show("This run is still being processed. The page updates when it is ready. ", "info", [bar]);
    const tick = async () => {
      if (stopped) return;
      try {
        const r = await apiFetch(`runs/${encId}`);
        if (r.status !== run.status) {
          window.dispatchEvent(new HashChangeEvent("hashchange"));
          return;
        }
      } catch {
        /* keep polling */
      }
      timer = setTimeout(tick, 1000);
    };
    timer = setTimeout(tick, 1000);
    return () => {
      stopped = true;
      clearTimeout(timer);
    };
  }
  if (run.status === "failed") {
    const facts = [];
    if (run.error && typeof run.error === "object") {
      for (const k of ["column", "row", "unit"]) if (run.error[k] !== undefined && run.error[k] !== null) facts.push(`${k}: ${run.error[k]}`);
    }
    status.show(`Processing this run failed: ${runErrorMessage(run.error)}`, "error",
      facts.length ? [h("ul", { class: "error-facts" }, facts.map((f) => h("li", {}, f)))] : []);
    main.appendChild(metadataSection(run));
    return null;
  }

  const [profile, spotsAnswer] = await chartData;
  const spots = (spotsAnswer || []).slice().sort((a, b) => a.start_m - b.start_m);

  // ---- summary -------------------------------------------------------------------------------
  // Over rough rail one pass cannot tell a soft support from the rail's own geometry: "no soft
  // spot" would claim what it cannot know, so the summary says what it can and cannot tell.
  // A pass never says "no soft spot" without what it could not have seen (its detection limit).
  const unseen = unseenText(run.detection_limit);
  const rough = run.stiffness_basis === "not separable";
  const deepest = spots.length ? fmt(Math.max(...spots.map((s) => s.depth_mm)), 2) : null;
  let said;
  if (rough) {
    said = spots.length === 0
      ? "No dip beyond this pass's detection limit. On its own, this pass cannot tell whether the supports here are sound: the rail's own geometry is larger than what a soft support adds."
      : `${plural(spots.length, "dip")} deeper than this pass's detection limit (deepest ${deepest} mm), listed by depth only: this pass alone cannot tell a soft support from the rail's own geometry.`;
  } else {
    said = spots.length === 0
      ? "No soft spot detected."
      : `${plural(spots.length, "soft spot")} detected — shaded in orange on the profile below, deepest ${deepest} mm.`;
  }
  const summary = h("p", { class: "summary", id: "run-summary" }, unseen ? `${said} ${unseen}` : said);
  main.appendChild(summary);
  // Honesty: where one pass cannot tell rail geometry from stiffness its dips are listed by
  // depth only; over smooth rail the single-pass losses stay, labelled as such.
  if (run.stiffness_message) {
    main.appendChild(h("div", { class: "message warning", role: "status", id: "run-stiffness-message" },
      "The track's stiffness map separates geometry from stiffness where passes of different wheel loads (or a survey) cover the rail, and lists the soft spots found there. ",
      h("a", { href: `#/tracks/${encodeURIComponent(run.track_id)}?view=stiffness`, id: "run-stiffness-link" }, "Open the track's stiffness map"), "."));
  } else if (run.stiffness_basis === "single pass") {
    main.appendChild(h("p", { class: "hint", id: "run-stiffness-basis" },
      "Stiffness losses from this pass alone (single pass): the rail is smooth at the noise level here."));
  }

  // ---- profile plot --------------------------------------------------------------------------
  const profileDiv = h("div", { class: "plot plot-profile", id: "profile-plot", role: "figure", "aria-label": "Loaded profile against chainage with soft spots shaded" });
  const axlesToggle = h("input", { type: "checkbox", id: "toggle-axles" });
  const baselineToggle = h("input", { type: "checkbox", id: "toggle-baseline" });
  const resolutionNote = h("p", { class: "hint", id: "profile-resolution" });
  const profileSection = h("section", { class: "card", "aria-labelledby": "profile-h" },
    h("div", { class: "section-head" },
      h("h2", { id: "profile-h" }, "Loaded profile"),
      h("div", { class: "toggles" },
        h("label", { class: "check" }, axlesToggle, " Front and rear axle profiles"),
        h("label", { class: "check" }, baselineToggle, " Baseline"))),
    h("details", { class: "help", id: "profile-help" },
      h("summary", {}, "What the chart shows"),
      h("ul", {}, [TERMS.loadedProfile, TERMS.baseline, TERMS.depth, TERMS.loss].map((t) => h("li", {}, t)))),
    profileDiv,
  );
  main.appendChild(profileSection);

  const P = await loadPlotly();
  const series = {
    fused: { key: "level_mm", name: "Fused level", line: { color: COLORS.fused, width: 1.6 }, hover: "fused" },
    front: { key: "front_level_mm", name: "Front axle", line: { color: COLORS.front, width: 1.1, dash: "dash" }, hover: "front" },
    rear: { key: "rear_level_mm", name: "Rear axle", line: { color: COLORS.rear, width: 1.1, dash: "dot" }, hover: "rear" },
    baseline: { key: "baseline_mm", name: "Baseline", line: { color: "#6b7280", width: 1, dash: "dashdot" }, hover: "baseline" },
  };
  const traceOf = (which, view) => ({
    type: "scatter", mode: "lines", name: series[which].name, meta: which,
    x: view.chainage_m, y: view[series[which].key], line: series[which].line,
    hovertemplate: `%{y:.3f} mm<extra>${series[which].hover}</extra>`,
  });
  let overview = profile;
  let current = profile;
  const traces = [traceOf("fused", profile)];
  if (spots.length) {
    traces.push({
      type: "scatter", mode: "markers", name: "Soft spot peaks", meta: "peaks",
      x: spots.map((s) => s.peak_m),
      y: spots.map((s) => interpAt(profile.chainage_m, profile.level_mm, s.peak_m, { nearest: true })),
      marker: { symbol: "triangle-down", size: 11, color: COLORS.spotLine, line: { color: "#1b1f24", width: 1 } },
      customdata: spots.map((s, i) => [i + 1, s.depth_mm, s.stiffness_loss_pct, s.start_m, s.end_m]),
      hovertemplate: "S%{customdata[0]}: depth %{customdata[1]:.2f} mm, stiffness loss %{customdata[2]:.0f} %<br>%{customdata[3]:.1f}–%{customdata[4]:.1f} m<extra></extra>",
    });
  }
  const margin = { l: 64, r: 24, t: 60, b: 96 };
  const labelRoom = { widthPx: profileDiv.clientWidth - margin.l - margin.r, range: [profile.chainage_m[0], profile.chainage_m.at(-1)] };
  const layout = baseLayout({ shapes: softSpotShapes(spots), annotations: softSpotLabels(spots, labelRoom), margin });
  await P.newPlot(profileDiv, traces, layout, CONFIG);
  profileSection.append(zoomControls(profileDiv, { label: "Profile plot view" }), resolutionNote);

  const describeResolution = (view) => {
    resolutionNote.textContent = view.decimated
      ? `${view.n_points.toLocaleString()} grid points in view, drawn as ${view.chainage_m.length.toLocaleString()} (lowest and highest per bucket, so no dip is lost). Zoom in for full detail.`
      : `${view.n_points.toLocaleString()} grid points at full resolution.`;
  };
  describeResolution(profile);

  const shown = (which) => profileDiv.data.findIndex((t) => t.meta === which);
  const applyView = (view) => {
    current = view;
    for (const which of Object.keys(series)) {
      const i = shown(which);
      if (i >= 0) P.restyle(profileDiv, { x: [view.chainage_m], y: [view[series[which].key]] }, [i]);
    }
    describeResolution(view);
  };
  const toggle = (which, on) => {
    const i = shown(which);
    if (on && i < 0) P.addTraces(profileDiv, traceOf(which, current));
    if (!on && i >= 0) P.deleteTraces(profileDiv, [i]);
  };
  axlesToggle.addEventListener("change", () => {
    toggle("front", axlesToggle.checked);
    toggle("rear", axlesToggle.checked);
    announce(axlesToggle.checked ? "Front and rear axle profiles shown." : "Axle profiles hidden.");
  });
  baselineToggle.addEventListener("change", () => toggle("baseline", baselineToggle.checked));

  // Zooming into a decimated profile fetches that window at the resolution the plot can show.
  let zoomTimer = null;
  let zoomSeq = 0;
  profileDiv.on("plotly_relayout", (ev) => {
    if (!overview.decimated) return;
    let range = null;
    if (ev["xaxis.range[0]"] !== undefined) range = [ev["xaxis.range[0]"], ev["xaxis.range[1]"]];
    else if (Array.isArray(ev["xaxis.range"])) range = ev["xaxis.range"];
    else if (ev["xaxis.autorange"]) range = "full";
    if (!range) return;
    clearTimeout(zoomTimer);
    zoomTimer = setTimeout(async () => {
      const seq = ++zoomSeq;
      if (range === "full") {
        applyView(overview);
        return;
      }
      const [a, b] = range.map(Number);
      const pad = (b - a) * 0.5;
      try {
        const view = await apiFetch(`/api/v1/views/runs/${encId}/profile?from_m=${a - pad}&to_m=${b + pad}&max_points=${MAX_POINTS}`);
        if (!stopped && seq === zoomSeq) applyView(view);
      } catch (err) {
        resolutionNote.textContent = `Cannot load this window: ${err.message}`;
      }
    }, 200);
  });

  // ---- soft spots table ----------------------------------------------------------------------
  const spotRows = spots.map((s, i) => h("tr", {},
    h("th", { scope: "row" }, `S${i + 1}`),
    h("td", { class: "num" }, fmt(s.start_m, 1)),
    h("td", { class: "num" }, fmt(s.end_m, 1)),
    h("td", { class: "num" }, fmt(s.peak_m, 1)),
    h("td", { class: "num" }, fmt(s.depth_mm, 2)),
    h("td", { class: "num" }, fmt(s.stiffness_loss_pct, 0)),
    h("td", {}, h("button", {
      type: "button", class: "button small", "aria-label": `Zoom the profile to soft spot S${i + 1}`,
      onclick: () => {
        zoomTo(profileDiv, s.start_m, s.end_m, 3);
        profileDiv.scrollIntoView({ behavior: "smooth", block: "center" });
        announce(`Zoomed to soft spot S${i + 1} at ${fmt(s.peak_m, 1)} m.`);
      },
    }, "Zoom"))));
  const csvName = `run-${id}-soft-spots.csv`;
  const downloads = h("div", { class: "downloads" },
    h("a", { class: "button secondary", href: `/api/v1/runs/${encId}/profile?format=csv`, download: `run-${id}-profile.csv`, id: "download-profile" }, "Profile (CSV)"),
    h("a", { class: "button secondary", href: `/api/v1/runs/${encId}/soft-spots.csv`, download: csvName, id: "download-spots-csv" }, "Soft spots (CSV)"),
    h("button", { type: "button", class: "button secondary", id: "download-spots-json", onclick: () => downloadBlob(new Blob([JSON.stringify(spots, null, 2)], { type: "application/json" }), `run-${id}-soft-spots.json`) }, "Soft spots (JSON)"),
  );
  main.appendChild(h("section", { class: "card", "aria-labelledby": "spots-h" },
    h("div", { class: "section-head" }, h("h2", { id: "spots-h" }, "Soft spots"), downloads),
    spots.length
      ? scrollTable("Soft spots of this run", h("table", { class: "data", id: "spots-table" },
        h("caption", { class: "visually-hidden" }, "Soft spots of this run, by chainage"),
        h("thead", {}, h("tr", {},
          h("th", { scope: "col" }, "#"), h("th", { scope: "col", class: "num" }, "Start (m)"), h("th", { scope: "col", class: "num" }, "End (m)"),
          h("th", { scope: "col", class: "num" }, "Peak (m)"),
          h("th", { scope: "col", class: "num" }, h("abbr", { title: TERMS.depth }, "Depth (mm)")),
          h("th", { scope: "col", class: "num" }, h("abbr", { title: TERMS.loss }, run.stiffness_basis === "single pass" ? "Stiffness loss (%, single pass)" : "Stiffness loss (%)")), h("th", { scope: "col" }, h("span", { class: "visually-hidden" }, "Actions")))),
        h("tbody", {}, spotRows)))
      : h("p", { class: "muted" }, `None detected. ${unseen}`),
  ));

  // ---- metadata and quality -----------------------------------------------------------------
  main.appendChild(metadataSection(run));

  // ---- raw signals ---------------------------------------------------------------------------
  const signalsDiv = h("div", { class: "plot plot-signals", id: "signals-plot", role: "figure", "aria-label": "Raw signals against time" });
  const signalsNote = h("p", { class: "hint" });
  main.appendChild(h("section", { class: "card", "aria-labelledby": "signals-h" },
    h("h2", { id: "signals-h" }, "Raw signals"), signalsNote, signalsDiv));
  loadSignals(encId, signalsDiv, signalsNote).catch((err) => {
    signalsNote.textContent = `The raw signals cannot be shown: ${err.message}`;
  });

  announce(`Run ${id}: ${spots.length} soft spots.`);
  return () => {
    stopped = true;
    clearTimeout(timer);
  };
}

async function loadSignals(encId, div, note) {
  const data = await apiGetOptional(`runs/${encId}/signals`);
  if (!data || !data.time_s || data.time_s.length === 0) {
    note.textContent = "The service does not keep this run's raw signals.";
    div.hidden = true;
    return;
  }
  note.textContent = data.decimated
    ? `Decimated for display to ${data.time_s.length.toLocaleString()} points (min/max per bucket, peaks kept) out of ${Number(data.n_samples).toLocaleString()} samples.`
    : `${data.time_s.length.toLocaleString()} samples.`;
  const n = data.time_s.length;
  const traces = [
    { type: "scatter", mode: "lines", name: "Vertical acceleration", x: data.time_s, y: data.accel_z_mps2, yaxis: "y", line: { color: COLORS.accel, width: 1 }, hovertemplate: "%{y:.4f} m/s²<extra>accel</extra>" },
    { type: "scatter", mode: "lines", name: "Pitch rate", x: data.time_s, y: data.pitch_rate_radps, yaxis: "y2", line: { color: COLORS.pitch, width: 1 }, hovertemplate: "%{y:.6f} rad/s<extra>pitch rate</extra>" },
  ];
  const hasSpeed = Array.isArray(data.speed_mps) && data.speed_mps.length === n;
  if (hasSpeed) {
    traces.push({ type: "scatter", mode: "lines", name: "Speed", x: data.time_s, y: data.speed_mps, yaxis: "y3", line: { color: COLORS.speed, width: 1.2 }, hovertemplate: "%{y:.2f} m/s<extra>speed</extra>" });
  }
  const layout = baseLayout({
    height: hasSpeed ? 460 : 360,
    xaxis: { title: { text: "Time (s)" }, gridcolor: "#e3e6ea", anchor: hasSpeed ? "y3" : "y2" },
    yaxis: { title: { text: "Accel (m/s²)" }, domain: hasSpeed ? [0.7, 1] : [0.55, 1], gridcolor: "#e3e6ea", automargin: true },
    yaxis2: { title: { text: "Pitch rate (rad/s)" }, domain: hasSpeed ? [0.36, 0.64] : [0, 0.45], gridcolor: "#e3e6ea", automargin: true },
    yaxis3: hasSpeed ? { title: { text: "Speed (m/s)" }, domain: [0, 0.28], gridcolor: "#e3e6ea", automargin: true } : undefined,
  });
  if (!hasSpeed) delete layout.yaxis3;
  await (await loadPlotly()).newPlot(div, traces, layout, CONFIG);
}

/** How the run was placed on the track: from its start chainage, or fitted to its GNSS fixes
 * along the track's centerline (method, fixes used/rejected, residual, scale, lateral offset). */
function placementBox(run) {
  const p = run.positioning;
  const box = h("div", { id: "run-placement" }, h("h3", {}, "Placement on the track"));
  if (!p) {
    box.append(h("p", {}, run.start_chainage_m === null || run.start_chainage_m === undefined
      ? "From the log's chainage column."
      : `From the start chainage given with the upload: ${fmtKm(run.start_chainage_m, 2)}, ${run.direction}.`));
    return box;
  }
  const dl = h("dl", { class: "meta", id: "run-placement-facts" });
  const rows = [
    ["Method", `GNSS fixes fitted to the track's centerline${p.pieces > 1 ? ` (odometer in ${p.pieces} pieces)` : ""}`],
    ["Start", `${fmtKm(p.start_chainage_m, 2)}, ${p.direction}`],
    ["Fixes used", `${p.n_used} of ${p.n_fixes} (${p.n_rejected} rejected: off the line or outliers)`],
    ["Residual (RMS)", `${fmt(p.residual_rms_m, 2)} m`],
    ["Odometer scale", `${fmt(p.scale, 4)} (true / logged distance)`],
    ["Lateral offset", `median ${fmt(p.offset_median_m, 2)} m, 95 % ${fmt(p.offset_p95_m, 2)} m`],
  ];
  for (const [k, v] of rows) dl.append(h("dt", {}, k), h("dd", {}, v));
  box.append(dl);
  return box;
}

function metadataSection(run) {
  const meta = run;
  const dl = h("dl", { class: "meta", id: "run-metadata" });
  dl.append(h("dt", {}, "Status"), h("dd", {}, h("span", { class: `status status-${run.status}` }, run.status)));
  for (const [key, label, format] of META_FIELDS) {
    if (meta[key] === undefined || meta[key] === null || meta[key] === "") continue;
    dl.append(h("dt", {}, label), h("dd", {}, format(meta[key])));
  }
  const quality = run.quality;
  const qBox = h("dl", { class: "meta", id: "run-quality" });
  if (quality && typeof quality === "object") {
    for (const [key, value] of Object.entries(quality)) {
      const spec = QUALITY_FIELDS[key];
      const label = spec ? spec[0] : key.replace(/_/g, " ");
      const text = typeof value === "number" ? `${fmt(value, spec ? spec[2] : 3)}${spec ? ` ${spec[1]}` : ""}` : String(value);
      qBox.append(h("dt", { title: spec ? spec[3] : "" }, label), h("dd", {}, text));
    }
  }
  return h("section", { class: "card two-col", "aria-labelledby": "meta-h" },
    h("div", {}, h("h2", { id: "meta-h" }, "Run metadata"), dl, placementBox(run)),
    h("div", {}, h("h2", {}, "Quality indicators"),
      quality ? qBox : h("p", { class: "muted" }, "No quality indicators for this run.")),
  );
}
