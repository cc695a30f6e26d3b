// Vehicles: the list (#/vehicles) and one vehicle's page (#/vehicles/{name}): its parameters
// and versions, calibrations (objective before/after and a plot of the fit), suspension-health
// alerts, and a button that calibrates it from its stored runs.

import { h, clear, announce, fmt, fmtDate, fmtDay, messageBox, scrollTable } from "../dom.js";
import { apiFetch, apiFetchAll, apiPostJson } from "../api.js";
import { baseLayout, COLORS, CONFIG, loadPlotly } from "../plots.js";

const PARAM_LABELS = {
  ms: ["Body mass m_s", "kg"], Is: ["Pitch inertia I_s", "kg m²"],
  mu1: ["Front axle mass", "kg"], mu2: ["Rear axle mass", "kg"],
  ks1: ["Front suspension k_s1", "N/m"], ks2: ["Rear suspension k_s2", "N/m"],
  cs1: ["Front damping c_s1", "N s/m"], cs2: ["Rear damping c_s2", "N s/m"],
  kt1: ["Front contact k_t1", "N/m"], kt2: ["Rear contact k_t2", "N/m"],
  d1: ["CG to front axle D1", "m"], d2: ["CG to rear axle D2", "m"],
  sensor_x_m: ["Accelerometer ahead of CG", "m"],
};
const POLL_MS = 1000;

const num = (v) => String(Number(Number(v).toPrecision(6)));
const pct = (v) => (v === null || v === undefined ? "—" : `${(100 * v).toFixed(1)} %`);

function changeText(f) {
  return f.name === "sensor_x_m" ? `${f.change >= 0 ? "+" : ""}${f.change.toFixed(2)} ± ${f.sd.toFixed(2)} m`
    : `${f.change >= 0 ? "+" : ""}${(100 * f.change).toFixed(1)} % ± ${(100 * f.sd).toFixed(1)} %`;
}

export async function render(main, params) {
  const name = params[0];
  if (!name) return renderList(main);
  main.appendChild(h("h1", {}, `Vehicle ${name}`));
  const status = messageBox("info");
  main.appendChild(status.el);

  const paramsSection = h("section", { class: "card", "aria-labelledby": "params-h", id: "vehicle-params" },
    h("h2", { id: "params-h" }, "Parameters"));
  const healthSection = h("section", { class: "card", "aria-labelledby": "health-h", id: "vehicle-health" },
    h("h2", { id: "health-h" }, "Suspension health"));
  const calSection = h("section", { class: "card", "aria-labelledby": "cal-h", id: "vehicle-calibrations" },
    h("h2", { id: "cal-h" }, "Calibrations"));
  const versionsSection = h("section", { class: "card", "aria-labelledby": "versions-h", id: "vehicle-versions" },
    h("h2", { id: "versions-h" }, "Parameter versions"));
  main.append(paramsSection, healthSection, calSection, versionsSection);

  // calibrate form
  const applyBox = h("input", { type: "checkbox", id: "cal-apply" });
  const sensorBox = h("input", { type: "checkbox", id: "cal-sensor" });
  const loadInput = h("input", { type: "number", id: "cal-load", min: "1", step: "any", placeholder: "registered" });
  const calBtn = h("button", { type: "button", class: "button primary", id: "calibrate" }, "Calibrate from its runs");
  const calMsg = messageBox("info");
  const calForm = h("div", { class: "calibrate-form" },
    h("p", { class: "muted" }, "Fits the pitch inertia and the suspension stiffnesses (relative to the body mass) so that the front and rear axles see the same rail. Applying a significant result makes a new version and reprocesses every run of the vehicle."),
    h("div", { class: "grid-3" },
      h("label", { for: "cal-apply" }, applyBox, " Apply if significant"),
      h("label", { for: "cal-sensor" }, sensorBox, " Also fit the accelerometer position"),
      h("div", { class: "field" }, h("label", { for: "cal-load" }, "Known body mass (kg, optional)"), loadInput)),
    calBtn, calMsg.el);
  const calList = h("div", { id: "calibration-list" });
  const fitPlot = h("div", { class: "plot", id: "calibration-plot", role: "figure", "aria-label": "Objective along each fitted parameter" });
  calSection.append(calForm, calList, fitPlot);

  let timer = null;
  const base = `vehicles/${encodeURIComponent(name)}`;

  async function load() {
    let vehicle, versions, cals, health;
    try {
      [vehicle, versions, cals, health] = await Promise.all([
        apiFetch(base), apiFetch(`${base}/versions`), apiFetch(`${base}/calibrations`), apiFetch(`${base}/health`),
      ]);
    } catch (err) {
      status.show(`Cannot load the vehicle: ${err.message}`, "error");
      return false;
    }
    fillParams(vehicle);
    fillVersions(versions);
    fillHealth(health);
    const items = cals.data;
    fillCalibrations(items);
    return items.some((c) => c.status === "running");
  }

  function fillParams(vehicle) {
    clear(paramsSection);
    paramsSection.appendChild(h("h2", { id: "params-h" }, `Parameters (version ${vehicle.version})`));
    const rows = Object.entries(vehicle.params).map(([k, v]) => {
      const [label, unit] = PARAM_LABELS[k] || [k, ""];
      return h("tr", {}, h("th", { scope: "row" }, label), h("td", { class: "num" }, num(v)), h("td", {}, unit));
    });
    paramsSection.appendChild(scrollTable("Current parameters", h("table", { class: "data", id: "params-table" },
      h("caption", { class: "visually-hidden" }, "Current parameters"),
      h("thead", {}, h("tr", {}, h("th", { scope: "col" }, "Parameter"), h("th", { scope: "col", class: "num" }, "Value"), h("th", { scope: "col" }, "Unit"))),
      h("tbody", {}, rows))));
  }

  function fillVersions(answer) {
    clear(versionsSection);
    versionsSection.appendChild(h("h2", { id: "versions-h" }, "Parameter versions"));
    const data = answer.data;
    const rows = data.map((v, i) => {
      const prev = data[i + 1];
      const changed = prev ? Object.keys(v.params).filter((k) => v.params[k] !== prev.params[k])
        .map((k) => `${k} ${num(prev.params[k])} → ${num(v.params[k])}`).join(", ") : "registered";
      return h("tr", {}, h("td", { class: "num" }, String(v.version)), h("td", {}, v.source),
        h("td", {}, v.calibration_id ? `calibration ${v.calibration_id}` : (v.created_by || "—")),
        h("td", {}, fmtDate(v.created_at)), h("td", {}, changed || "—"), h("td", {}, v.note || ""));
    });
    versionsSection.appendChild(scrollTable("Parameter versions", h("table", { class: "data", id: "versions-table" },
      h("caption", { class: "visually-hidden" }, "Parameter versions, newest first"),
      h("thead", {}, h("tr", {}, ...["Version", "Made by", "From", "When", "Changes", "Note"].map((t) => h("th", { scope: "col" }, t)))),
      h("tbody", {}, rows))));
  }

  function fillHealth(health) {
    clear(healthSection);
    healthSection.appendChild(h("h2", { id: "health-h" }, "Suspension health"));
    if (!health.alerts.length) {
      healthSection.appendChild(h("p", { id: "health-ok" }, health.history.length
        ? "No calibrated parameter has changed beyond its uncertainty."
        : "No calibration yet: calibrate the vehicle to start its health history."));
      return;
    }
    const list = h("ul", { class: "alert-list", id: "health-alerts" });
    for (const a of health.alerts) {
      list.appendChild(h("li", { class: "message error" },
        h("strong", {}, `${a.parameter}: ${num(a.before)} → ${num(a.after)} (${a.change >= 0 ? "+" : ""}${(100 * a.change).toFixed(0)} %)`),
        ` since ${fmtDay(a.since)} — ${a.sigmas.toFixed(1)} standard uncertainties (${a.reference} → ${a.source})`));
    }
    healthSection.appendChild(list);
  }

  function fillCalibrations(items) {
    clear(calList);
    if (!items.length) {
      calList.appendChild(h("p", { class: "muted" }, "No calibration yet."));
      fitPlot.hidden = true;
      return;
    }
    const rows = items.map((c) => h("tr", { "data-status": c.status },
      h("td", { class: "num" }, String(c.id)), h("td", {}, c.status + (c.automatic ? " (automatic)" : "")),
      h("td", {}, fmtDate(c.created_at)), h("td", { class: "num" }, String(c.runs_used.length)),
      h("td", {}, c.objective_before === null ? "—" : `${pct(c.objective_before)} → ${pct(c.objective_after)}`),
      h("td", {}, c.fitted.length ? c.fitted.map((f) => `${f.name} ${changeText(f)}${c.applied && f.applied === false ? " (kept as registered)" : ""}`).join("; ") : "—"),
      h("td", {}, c.applied ? `applied: version ${c.applied_version}` : (c.apply ? "not applied" : "—")),
      h("td", {}, c.status === "failed" ? (c.error?.message || "failed") : (c.message || ""))));
    calList.appendChild(scrollTable("Calibrations", h("table", { class: "data", id: "calibrations-table" },
      h("caption", { class: "visually-hidden" }, "Calibrations, newest first"),
      h("thead", {}, h("tr", {}, ...["#", "Status", "Requested", "Runs", "Axle disagreement", "Fitted change", "Applied", "Result"].map((t) => h("th", { scope: "col" }, t)))),
      h("tbody", {}, rows))));
    const last = items.find((c) => c.status === "done" && c.details && c.details.scans);
    if (last) plotFit(last);
  }

  function plotFit(cal) {
    fitPlot.hidden = false;
    const traces = Object.entries(cal.details.scans).map(([pname, scan], i) => ({
      x: scan.change.map((v) => (pname === "sensor_x_m" ? v : 100 * v)),
      y: scan.objective.map((v) => 100 * v),
      mode: "lines+markers", type: "scatter", name: pname === "sensor_x_m" ? `${pname} (m)` : `${pname} (%)`,
      line: { color: [COLORS.fused, COLORS.front, COLORS.rear, COLORS.pitch, COLORS.speed][i % 5] },
    }));
    try {
      loadPlotly().then((P) => P.react(fitPlot, traces, baseLayout({
        title: { text: `Calibration ${cal.id}: front/rear disagreement along each fitted parameter`, font: { size: 14 } },
        xaxis: { title: { text: "Change from the registered value (% or m)" }, zeroline: true },
        yaxis: { title: { text: "Disagreement (% of level)" } },
        hovermode: "closest",
      }), CONFIG)).catch((err) => {
        fitPlot.textContent = err.message;
      });
    } catch (err) {
      fitPlot.textContent = err.message;
    }
  }

  calBtn.addEventListener("click", async () => {
    const body = { apply: applyBox.checked };
    if (sensorBox.checked) body.fit = ["Is", "ks1", "ks2", "sensor_x_m"];
    if (loadInput.value !== "") {
      const load = Number(loadInput.value);
      if (!Number.isFinite(load) || load <= 0) {
        calMsg.show("The body mass must be a positive number of kg.", "error");
        loadInput.focus();
        return;
      }
      body.load_kg = load;
    }
    calBtn.disabled = true;
    try {
      const answer = await apiPostJson(`${base}/calibrate`, body);
      calMsg.show(`Calibration ${answer.id} is running…`, "info");
      announce(`Calibration ${answer.id} started`);
      schedule();
    } catch (err) {
      calMsg.show(err.message, "error");
    } finally {
      calBtn.disabled = false;
    }
  });

  function schedule() {
    if (timer) clearTimeout(timer);
    timer = setTimeout(async () => {
      timer = null;
      const running = await load();
      if (running) schedule();
      else if (!calMsg.el.hidden && calMsg.el.classList.contains("info")) {
        calMsg.show("Calibration finished (see the table).", "success");
      }
    }, POLL_MS);
  }

  if (await load()) schedule();
  return () => { if (timer) clearTimeout(timer); };
}

async function renderList(main) {
  main.appendChild(h("h1", {}, "Vehicles"));
  const status = messageBox("info");
  main.appendChild(status.el);
  let vehicles;
  try {
    vehicles = await apiFetchAll("vehicles");
  } catch (err) {
    status.show(`Cannot load the vehicles: ${err.message}`, "error");
    return null;
  }
  const list = h("ul", { class: "track-list", id: "vehicle-list" });
  for (const v of vehicles) {
    list.appendChild(h("li", {}, h("a", { href: `#/vehicles/${encodeURIComponent(v.name)}` }, v.name),
      h("span", { class: "muted" }, ` · version ${v.version}`),
      v.description ? h("p", { class: "muted small" }, v.description) : null));
  }
  main.appendChild(h("section", { class: "card" }, list));
  return null;
}
