// Simulate page: a synthetic run from the forward model (speed, soft zones, sensor noise), its
// signals, and the profile the engine recovers from them next to the true one. Uses the
// service's POST /api/v1/simulate, which stores the run (track "simulated") and returns the truth.

import { h, clear, append, announce, field, fmt, messageBox } from "../dom.js";
import { ApiError, apiFetch, apiFetchAll, apiPostJson, apiSchema } from "../api.js";
import { applyBounds, numberProblem } from "../formerrors.js";
import { baseLayout, COLORS, CONFIG, loadPlotly, softSpotLabels, softSpotShapes, zoomControls } from "../plots.js";
import { unseenText } from "../visibility.js";

const NOISE_PRESETS = {
  none: { accel_noise: 0, gyro_noise: 0, accel_bias: 0, gyro_bias: 0 },
  typical: { accel_noise: 0.005, gyro_noise: 1e-4, accel_bias: 0.02, gyro_bias: 2e-4 },
  poor: { accel_noise: 0.02, gyro_noise: 5e-4, accel_bias: 0.05, gyro_bias: 5e-4 },
};


export async function render(main) {
  let stopped = false;
  main.appendChild(h("h1", {}, "Simulate a run"));
  main.appendChild(h("p", { class: "lead" },
    "Drive the half-car model over a track with soft zones you choose, add sensor noise, and see what the engine recovers. The true loaded level under the wheels is drawn next to the recovered profile."));

  const form = h("form", { class: "sim-form card", id: "simulate-form", novalidate: true });
  // Bounds: the service's own (its schema, applied below), never copied here.
  const lengthInput = h("input", { type: "number", id: "sim-length", value: "300", step: "any", required: true });
  const speedInput = h("input", { type: "number", id: "sim-speed", value: "80", step: "any", required: true });
  const seedInput = h("input", { type: "number", id: "sim-seed", value: "1", step: "1" });
  const zonesBody = h("tbody", {});
  let zoneProps = null; // ZoneSpec's properties, once the schema is here
  const zoneBounds = (s, e, l) => {
    if (!zoneProps) return;
    applyBounds(s, zoneProps.start_m);
    applyBounds(e, zoneProps.end_m);
    applyBounds(l, zoneProps.loss, 0.01); // % shown, a fraction sent
  };
  const addZone = (start, end, loss) => {
    const s = h("input", { type: "number", step: "any", value: String(start), "aria-label": "Zone start (m)", class: "zone-start" });
    const e = h("input", { type: "number", step: "any", value: String(end), "aria-label": "Zone end (m)", class: "zone-end" });
    const l = h("input", { type: "number", step: "any", value: String(loss), "aria-label": "Stiffness loss (%)", class: "zone-loss" });
    zoneBounds(s, e, l);
    const row = h("tr", {}, h("td", {}, s), h("td", {}, e), h("td", {}, l),
      h("td", {}, h("button", { type: "button", class: "button small", "aria-label": "Remove this zone", onclick: () => row.remove() }, "Remove")));
    zonesBody.appendChild(row);
    return s;
  };
  addZone(100, 106, 50);
  addZone(200, 204, 35);
  const noiseInputs = {
    accel_noise: h("input", { type: "number", id: "sim-accel-noise", step: "any" }),
    gyro_noise: h("input", { type: "number", id: "sim-gyro-noise", step: "any" }),
    accel_bias: h("input", { type: "number", id: "sim-accel-bias", step: "any" }),
    gyro_bias: h("input", { type: "number", id: "sim-gyro-bias", step: "any" }),
  };
  const presetSel = h("select", { id: "sim-noise-preset" },
    h("option", { value: "typical" }, "Typical logger"),
    h("option", { value: "none" }, "Noise-free"),
    h("option", { value: "poor" }, "Poor sensor"),
    h("option", { value: "custom" }, "Custom"));
  const applyPreset = (key) => {
    const p = NOISE_PRESETS[key];
    if (!p) return;
    for (const [k, input] of Object.entries(noiseInputs)) input.value = String(p[k]);
  };
  applyPreset("typical");
  presetSel.addEventListener("change", () => applyPreset(presetSel.value));
  for (const input of Object.values(noiseInputs)) {
    input.addEventListener("input", () => {
      presetSel.value = "custom";
    });
  }

  // IMU grade: a class of real sensor (noise densities, per-pass bias, wander, quantisation,
  // jitter; the service's SENSOR_GRADES) instead of the figures typed below.
  const gradeSel = h("select", { id: "sim-sensor-grade" }, h("option", { value: "" }, "The noise figures below"));
  const syncGrade = () => {
    for (const input of Object.values(noiseInputs)) input.disabled = gradeSel.value !== "";
    presetSel.disabled = gradeSel.value !== "";
  };
  gradeSel.addEventListener("change", syncGrade);
  apiFetch("/api/v1/simulate/sensor-grades").then((grades) => {
    for (const [name, g] of Object.entries(grades)) {
      gradeSel.appendChild(h("option", { value: name }, `${g.label}: ${fmt(g.accel_density_ug, 0)} µg/√Hz, ${fmt(g.gyro_arw_deg_rth, 2)} °/√h`));
    }
  }).catch(() => {});

  // Vehicle (a stored vehicle or an engine preset such as "heavy") and rail geometry (a
  // straight rail, or a random profile of a standard spectrum: the same spectrum and seed is the
  // same physical track, so runs of different vehicles over it can be separated).
  const vehicleSel = h("select", { id: "sim-vehicle" }, h("option", { value: "table1" }, "table1"));
  const railSel = h("select", { id: "sim-rail" }, h("option", { value: "" }, "Straight rail (the paper's case)"));
  const railSeedInput = h("input", { type: "number", id: "sim-rail-seed", value: "0", step: "1" });
  // The track the simulated run is stored on: an existing one (its nominal properties apply)
  // or a new name; blank: "simulated" (or one track per rail spectrum and seed).
  const trackInput = h("input", { type: "text", id: "sim-track", list: "sim-track-list", maxlength: 200, autocomplete: "off", placeholder: "its own simulated track" });
  const trackList = h("datalist", { id: "sim-track-list" });
  apiFetchAll("tracks").then((tracks) => {
    for (const t of tracks) trackList.appendChild(h("option", { value: t.name }));
  }).catch(() => {});
  Promise.all([
    apiFetch("/api/v1/vehicles/presets").catch(() => ({})),
    apiFetchAll("vehicles").then((data) => ({ data })).catch(() => null),
    apiFetch("/api/v1/simulate/spectra").catch(() => ({})),
  ]).then(([presets, stored, spectra]) => {
    const names = new Set([...Object.keys(presets), ...(stored ? stored.data.map((v) => v.name) : [])]);
    vehicleSel.replaceChildren(...[...names].sort().map((n) => h("option", { value: n, selected: n === "table1" }, n)));
    for (const name of Object.keys(spectra)) railSel.appendChild(h("option", { value: name }, name));
  });

  const lengthHint = "At most 120 s of travel.";
  apiSchema().then((spec) => {
    const schemas = spec.components.schemas;
    const req = schemas.SimulateRequest.properties;
    const length = applyBounds(lengthInput, req.length_m);
    applyBounds(speedInput, req.speed_mps, 1 / 3.6); // km/h shown, m/s sent
    applyBounds(seedInput, req.seed);
    applyBounds(railSeedInput, schemas.IrregularitySpec.properties.seed);
    for (const [k, input] of Object.entries(noiseInputs)) applyBounds(input, schemas.SensorSpec.properties[k]);
    zoneProps = schemas.ZoneSpec.properties;
    for (const row of zonesBody.querySelectorAll("tr")) zoneBounds(row.querySelector(".zone-start"), row.querySelector(".zone-end"), row.querySelector(".zone-loss"));
    const hint = document.getElementById("sim-length-hint");
    if (hint && length.min !== undefined && length.max !== undefined) hint.textContent = `${length.min} to ${length.max} m; ${lengthHint.toLowerCase()}`;
  }).catch(() => {});

  const runBtn = h("button", { type: "submit", class: "button primary", id: "simulate-button" }, "Simulate and recover");
  const bar = h("progress", { max: "1", hidden: true, "aria-label": "Simulation progress" });
  const status = messageBox("info");
  status.el.id = "sim-status";

  append(form, [
    h("div", { class: "sim-grid" },
      h("fieldset", {},
        h("legend", {}, "Track and speed"),
        field("Track length (m)", lengthInput, lengthHint),
        field("Speed (km/h)", speedInput),
        field("Random seed", seedInput, "Same seed, same noise.")),
      h("fieldset", {},
        h("legend", {}, "Vehicle and rail"),
        field("Vehicle", vehicleSel, "table1: the paper's coach; heavy: about twice its wheel load."),
        field("Rail geometry", railSel, "A standard spectrum puts real-track irregularity under the wheels."),
        field("Rail seed", railSeedInput, "Same spectrum and seed, same track: runs of different vehicles over it separate geometry from stiffness."),
        h("div", {}, field("Store on track", trackInput, "An existing track or a new name; blank: a track of its own for this simulated track (rail, length, zones, seed), never mixed with real runs."), trackList)),
      h("fieldset", {},
        h("legend", {}, "Soft zones"),
        h("table", { class: "data compact", id: "sim-zones" },
          h("thead", {}, h("tr", {},
            h("th", { scope: "col" }, "Start (m)"), h("th", { scope: "col" }, "End (m)"), h("th", { scope: "col" }, "Loss (%)"),
            h("th", { scope: "col" }, h("span", { class: "visually-hidden" }, "Actions")))),
          zonesBody),
        h("button", { type: "button", class: "button small", onclick: () => addZone(150, 154, 40).focus() }, "Add a zone")),
      h("fieldset", {},
        h("legend", {}, "Sensor noise"),
        field("IMU grade", gradeSel, "A class of real IMU, or your own figures."),
        field("Preset", presetSel),
        h("div", { class: "grid-2" },
          field("Accel noise σ (m/s²)", noiseInputs.accel_noise),
          field("Gyro noise σ (rad/s)", noiseInputs.gyro_noise),
          field("Accel bias (m/s²)", noiseInputs.accel_bias),
          field("Gyro bias (rad/s)", noiseInputs.gyro_bias)))),
    h("div", { class: "actions" }, runBtn, bar, status.el),
  ]);
  main.appendChild(form);

  const results = h("div", { class: "sim-results", id: "sim-results", hidden: true });
  main.appendChild(results);

  function readForm() {
    const length = Number(lengthInput.value);
    const speedKmh = Number(speedInput.value);
    const errors = [];
    // Out of the service's bounds (its schema): "Speed (km/h) must be at least 18 and at most 288".
    const check = (input, label, required = false) => {
      const problem = numberProblem(input, { required });
      if (problem) errors.push([input, `${label} ${problem}.`]);
      return !problem;
    };
    check(lengthInput, "The track length (m)", true);
    check(speedInput, "The speed (km/h)", true);
    check(seedInput, "The random seed");
    check(railSeedInput, "The rail seed");
    const zones = [];
    for (const row of zonesBody.querySelectorAll("tr")) {
      const [si, ei, li] = [".zone-start", ".zone-end", ".zone-loss"].map((c) => row.querySelector(c));
      const s = Number(si.value);
      const e = Number(ei.value);
      const l = Number(li.value);
      if (!(si.value.trim() && ei.value.trim() && Number.isFinite(s) && Number.isFinite(e) && e > s)) errors.push([ei, `A zone must end after it starts (${s}–${e} m).`]);
      else if (!check(li, `The stiffness loss of zone ${s}–${e} m (%)`, true)) continue;
      else if (s < 0 || e > length) errors.push([si, `Zone ${s}–${e} m is outside the track (0–${length} m).`]);
      else zones.push({ start_m: s, end_m: e, loss: l / 100 });
    }
    const noise = {};
    for (const [k, input] of Object.entries(noiseInputs)) {
      if (!input.disabled) check(input, `The ${k.replace("_", " ")}`);
      noise[k] = Number(input.value || 0);
    }
    const seed = seedInput.value === "" ? 0 : Math.max(0, Math.trunc(Number(seedInput.value)));
    const railSeed = railSeedInput.value === "" ? 0 : Math.max(0, Math.trunc(Number(railSeedInput.value)));
    const rail = railSel.value ? { spectrum: railSel.value, seed: railSeed } : null;
    return { errors, request: { length_m: length, speed_mps: speedKmh / 3.6, zones, ...noise, sensor_grade: gradeSel.value || null, seed, vehicle: vehicleSel.value, rail, track: trackInput.value.trim() || null } };
  }

  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    for (const el of form.querySelectorAll("[aria-invalid]")) el.removeAttribute("aria-invalid");
    const { errors, request } = readForm();
    if (errors.length) {
      for (const [el] of errors) el.setAttribute("aria-invalid", "true");
      status.show("Please correct the form:", "error", [h("ul", { class: "error-facts" }, errors.map(([, m]) => h("li", {}, m)))]);
      errors[0][0].focus();
      return;
    }
    runBtn.disabled = true;
    bar.hidden = false;
    bar.removeAttribute("value");
    status.show("Simulating the run, then recovering the profile from its signals…", "info");
    const t0 = performance.now();
    try {
      const answer = await apiPostJson("simulate?wait=true", simulateBody(request));
      const id = answer.run.id;
      if (answer.run.status === "failed") throw new Error(answer.run.error ? answer.run.error.message : "processing failed");
      const enc = encodeURIComponent(id);
      const [profile, spots, signals] = await Promise.all([
        apiFetch(`/api/v1/views/runs/${enc}/profile?max_points=6000`),
        apiFetch(`runs/${enc}/soft-spots`),
        apiFetch(`runs/${enc}/signals`).catch(() => null),
      ]);
      if (stopped) return;
      const result = { truth: answer.truth, zones: answer.truth.zones, profile, soft_spots: spots, signals };
      await showResults(result);
      const n = result.soft_spots.length;
      const link = h("a", { href: `#/runs/${enc}`, id: "sim-run-link" }, `open it as run ${id}`);
      status.show(`Done in ${((performance.now() - t0) / 1000).toFixed(1)} s: ${n} soft spot${n === 1 ? "" : "s"} recovered for ${request.zones.length} true zone${request.zones.length === 1 ? "" : "s"}. ${answer.run.detection_limit ? `${unseenText(answer.run.detection_limit)} ` : ""}The run is stored on the track “${answer.run.track}”; `, "success", [link, "."]);
      announce("Simulation done.");
    } catch (err) {
      status.show(`The simulation failed: ${err.message}`, "error",
        err instanceof ApiError && err.items.length ? [h("ul", { class: "error-facts" }, err.items.map((i) => h("li", {}, i)))] : []);
    } finally {
      runBtn.disabled = false;
      bar.hidden = true;
    }
  });

  async function showResults(r) {
    clear(results);
    results.hidden = false;
    const P = await loadPlotly();
    const profileDiv = h("div", { class: "plot plot-profile", id: "sim-profile-plot", role: "figure", "aria-label": "Recovered profile and true profile against chainage" });
    const signalsDiv = h("div", { class: "plot plot-signals", id: "sim-signals-plot", role: "figure", "aria-label": "Synthetic signals against time" });
    const profileSection = h("section", { class: "card", "aria-labelledby": "sim-profile-h" },
      h("h2", { id: "sim-profile-h" }, "Recovered profile and truth"),
      h("p", { class: "hint" }, `Blue: the profile the engine recovers from the noisy signals. Black dashed: the true loaded level under the wheels (mean of both axles). Both are drawn about their own baseline as the server draws the one soft spots are measured from (a ${fmt(r.truth.baseline_window_m, 0)} m running median, smoothed). Blue strips along the top: the true soft zones; orange bands: the soft spots detected (both in the legend).`),
      profileDiv);
    results.append(profileSection);

    const rec = aboutBaseline(r.profile.level_mm, r.profile.baseline_mm);
    const traces = [{
      type: "scatter", mode: "lines", name: "Recovered", x: r.profile.chainage_m, y: rec,
      line: { color: COLORS.fused, width: 1.8 }, hovertemplate: "%{y:.3f} mm<extra>recovered</extra>",
    }];
    if (r.truth && r.truth.chainage_m) {
      traces.push({
        type: "scatter", mode: "lines", name: "Truth", x: r.truth.chainage_m,
        y: aboutBaseline(r.truth.level_mm, r.truth.baseline_mm),
        line: { color: COLORS.truth, width: 1.4, dash: "dash" }, hovertemplate: "%{y:.3f} mm<extra>truth</extra>",
      });
    }
    // The true zones are strips along the top and the detected spots full-height bands, so that
    // where they overlap both stay readable (same-height translucent bands blend into one).
    const trueShapes = softSpotShapes(r.zones || [], { fill: "rgba(0, 114, 178, 0.55)", line: COLORS.truthLine, name: "true-zone" })
      .map((sh) => ({ ...sh, y0: 0.9, y1: 1, layer: "above", line: { color: COLORS.truthLine, width: 1 } }));
    // Shapes have no legend entries: one legend-only trace per band kind names them.
    const legendOnly = (name, color, meta) => ({
      type: "scatter", mode: "markers", x: [null], y: [null], name, meta, hoverinfo: "skip",
      marker: { symbol: "square", size: 14, color, line: { color: "#1b1f24", width: 1 } },
    });
    if ((r.zones || []).length) traces.push(legendOnly("True soft zone", "rgba(0, 114, 178, 0.55)", "legend-true-zone"));
    if ((r.soft_spots || []).length) traces.push(legendOnly("Detected soft spot", "rgba(230, 159, 0, 0.45)", "legend-detected"));
    const layout = baseLayout({
      shapes: [...trueShapes, ...softSpotShapes(r.soft_spots)],
      annotations: softSpotLabels(r.soft_spots),
      margin: { l: 64, r: 24, t: 60, b: 96 },
      yaxis: { title: { text: "Level about its baseline (mm)" }, gridcolor: "#e3e6ea", zerolinecolor: "#9aa3ad" },
    });
    await P.newPlot(profileDiv, traces, layout, CONFIG);
    profileSection.appendChild(zoomControls(profileDiv, { label: "Simulated profile view" }));

    results.append(comparisonTable(r));

    const s = r.signals;
    if (!s || !s.time_s) return;
    results.append(h("section", { class: "card", "aria-labelledby": "sim-signals-h" },
      h("h2", { id: "sim-signals-h" }, "Synthetic signals"),
      h("p", { class: "hint" }, s.decimated
        ? `What the simulated sensor wrote (noise and bias included), drawn as ${s.time_s.length.toLocaleString()} points (lowest and highest per bucket) of ${Number(s.n_samples).toLocaleString()} samples.`
        : `What the simulated sensor wrote (noise and bias included): ${Number(s.n_samples).toLocaleString()} samples.`),
      signalsDiv));
    await P.newPlot(signalsDiv, [
      { type: "scatter", mode: "lines", name: "Vertical acceleration", x: s.time_s, y: s.accel_z_mps2, line: { color: COLORS.accel, width: 1 }, hovertemplate: "%{y:.4f} m/s²<extra>accel</extra>" },
      { type: "scatter", mode: "lines", name: "Pitch rate", x: s.time_s, y: s.pitch_rate_radps, yaxis: "y2", line: { color: COLORS.pitch, width: 1 }, hovertemplate: "%{y:.6f} rad/s<extra>pitch rate</extra>" },
    ], baseLayout({
      height: 360,
      xaxis: { title: { text: "Time (s)" }, gridcolor: "#e3e6ea", anchor: "y2" },
      yaxis: { title: { text: "Accel (m/s²)" }, domain: [0.55, 1], gridcolor: "#e3e6ea", automargin: true },
      yaxis2: { title: { text: "Pitch rate (rad/s)" }, domain: [0, 0.45], gridcolor: "#e3e6ea", automargin: true },
    }), CONFIG);
  }

  return () => {
    stopped = true;
  };
}

/** The service's POST /api/v1/simulate body for the form's request. */
function simulateBody(req) {
  const quiet = req.accel_noise === 0 && req.gyro_noise === 0 && req.accel_bias === 0 && req.gyro_bias === 0;
  const sensor = req.sensor_grade ? { sensor_grade: req.sensor_grade } : {
    sensor: quiet ? "ideal" : {
      accel_noise: req.accel_noise, gyro_noise: req.gyro_noise, accel_bias: req.accel_bias, gyro_bias: req.gyro_bias,
    },
  };
  return {
    // an irregular rail is a track of its own (spectrum and seed): runs over it can be compared
    // blank: the service's own track for this simulated track (rail, length, zones, seed)
    track: req.track || null,
    vehicle: req.vehicle || "table1",
    irregularity: req.rail,
    length_m: req.length_m,
    speed_mps: req.speed_mps,
    zones: req.zones,
    ...sensor,
    seed: req.seed,
  };
}

/** Level minus the baseline the server serves beside it (null where either is missing). */
function aboutBaseline(level, baseline) {
  return level.map((y, i) => (y === null || baseline[i] === null ? null : y - baseline[i]));
}

function comparisonTable(r) {
  const overlaps = (s, z) => s.end_m >= z.start_m - 3 && s.start_m <= z.end_m + 3;
  const rows = (r.zones || []).map((z, i) => {
    const match = r.soft_spots.find((s) => overlaps(s, z));
    return h("tr", {},
      h("th", { scope: "row" }, `Z${i + 1}`),
      h("td", { class: "num" }, `${fmt(z.start_m, 1)}–${fmt(z.end_m, 1)}`),
      h("td", { class: "num" }, fmt(z.loss * 100, 0)),
      h("td", {}, match ? h("span", { class: "status status-done" }, "found") : h("span", { class: "status status-failed" }, "missed")),
      h("td", { class: "num" }, match ? `${fmt(match.start_m, 1)}–${fmt(match.end_m, 1)}` : "—"),
      h("td", { class: "num" }, match ? fmt(match.depth_mm, 2) : "—"),
      h("td", { class: "num" }, match ? fmt(match.stiffness_loss_pct, 0) : "—"));
  });
  const extra = r.soft_spots.filter((s) => !(r.zones || []).some((z) => overlaps(s, z)));
  return h("section", { class: "card", "aria-labelledby": "sim-compare-h" },
    h("h2", { id: "sim-compare-h" }, "True zones and what was found"),
    h("div", { class: "table-scroll" }, h("table", { class: "data", id: "sim-compare" },
      h("thead", {}, h("tr", {},
        h("th", { scope: "col" }, "#"), h("th", { scope: "col" }, "True zone (m)"), h("th", { scope: "col" }, "True loss (%)"),
        h("th", { scope: "col" }, "Result"), h("th", { scope: "col" }, "Detected (m)"), h("th", { scope: "col" }, "Depth (mm)"),
        h("th", { scope: "col" }, "Estimated loss (%)"))),
      h("tbody", {}, rows))),
    extra.length ? h("p", { class: "hint" }, `${extra.length} detection${extra.length === 1 ? "" : "s"} away from any true zone (false alarm${extra.length === 1 ? "" : "s"}).`) : null);
}
