// Track intelligence on the track view: the defect register's columns, the aggregated
// profile plot, the alerts since a date, the limits form and the export links. Every value
// from the API is shown through text nodes (h(), textContent); nothing is parsed as HTML.

import { h, clear, append, announce, fmt, fmtDay, fmtKm, fmtKmRange, field, messageBox, plural, scrollTable } from "./dom.js";
import { ApiError, apiFetch, apiSchema } from "./api.js";
import { applyBounds, clearFieldErrors, numberProblem, showFieldError, showServerErrors } from "./formerrors.js";
import { baseLayout, COLORS, CONFIG, loadPlotly, TERMS } from "./plots.js";
import { provisionalLabel } from "./provisional.js";

export const LEVEL_LABELS = { immediate: "Immediate action", intervention: "Intervention", alert: "Alert" };
const SHORT_LEVEL = { immediate: "Immediate", intervention: "Intervention", alert: "Alert" };

// Level colours with a distinct dash per level, so the shading reads without colour vision.
const LEVEL_STYLE = {
  immediate: { fill: "rgba(178, 24, 43, 0.22)", line: "#8a0f24", dash: "solid" },
  intervention: { fill: "rgba(230, 97, 1, 0.20)", line: "#8c2d04", dash: "dash" },
  alert: { fill: "rgba(242, 169, 0, 0.20)", line: "#7a5a00", dash: "dot" },
  none: { fill: "rgba(107, 114, 128, 0.12)", line: "#4b5563", dash: "dashdot" },
};

function signed(v, digits) {
  if (v === null || v === undefined) return "—";
  const text = fmt(Math.abs(v), digits);
  if (Number(text) === 0) return text;
  return `${v > 0 ? "+" : "−"}${text}`;
}

/** A trend needs two successive sightings of the kind the figures come from: a defect seen
 * once, or one separation, has none (shown "—", not "0.000"). */
function trendOf(d, key) {
  const main = Array.isArray(d.evidence) && d.evidence.length ? d.evidence[0].sightings : d.runs_seen;
  return main >= 2 ? d[key] : null;
}

/** "separated: 4 passes, 2 loads" (of the runs covering it); older answers: "3 of 4". */
export function evidenceOf(d) {
  const covering = d.runs_covering > d.runs_seen ? ` (of ${d.runs_covering} covering)` : "";
  return d.evidence_text ? `${d.evidence_text}${covering}` : `${d.runs_seen} of ${d.runs_covering}`;
}

/** The loss with its band where the evidence gives one: "46 (38–55)". */
export function lossOf(d) {
  const v = fmt(d.stiffness_loss_pct, 0);
  if (d.stiffness_loss_lo_pct == null || d.stiffness_loss_hi_pct == null || d.stiffness_loss_pct == null) return v;
  return `${v} (${fmt(d.stiffness_loss_lo_pct, 0)}–${fmt(d.stiffness_loss_hi_pct, 0)})`;
}

/** Columns of the register table (the first is the rank, drawn as the row header). */
export const REGISTER_COLUMNS = [
  { key: "rank", label: "Rank", num: true, get: (d) => d.rank },
  // Priority and level first after the rank: on a phone (390 px) the first columns show.
  { key: "priority", label: "Priority", num: true, get: (d) => d.priority, show: (d) => String(d.priority) },
  { key: "level", label: "Level", title: "Limit level reached by the latest run (none: below the alert limits)", get: (d) => (d.level ? 3 - ["alert", "intervention", "immediate"].indexOf(d.level) : 9), show: (d) => (d.level ? SHORT_LEVEL[d.level] : "none"), cls: (d) => `level level-${d.level || "none"}` },
  { key: "start_m", label: "Zone", title: "Extent, chainage in km+m", num: true, get: (d) => d.start_m, show: (d) => fmtKmRange(d.start_m, d.end_m) },
  { key: "peak_m", label: "Peak", title: "Deepest point, chainage in km+m", num: true, get: (d) => d.peak_m, show: (d) => fmtKm(d.peak_m) },
  { key: "status", label: "Status", get: (d) => d.status, show: (d) => d.status, cls: (d) => `defect-status defect-${d.status}` },
  { key: "runs_seen", label: "Evidence", title: "What supports the defect: single passes, or the separation of geometry from stiffness across passes of different wheel loads (passes that support it of the runs covering it); provisional: separated with a vehicle neither calibrated nor with its runs' loads declared", get: (d) => d.runs_seen, show: (d) => [evidenceOf(d), provisionalLabel(d)], cls: () => "evidence" },
  { key: "depth_mm", label: "Depth (mm)", title: TERMS.depth, num: true, get: (d) => d.depth_mm, show: (d) => fmt(d.depth_mm, 2) },
  { key: "stiffness_loss_pct", label: "Loss (%)", title: `${TERMS.loss} (with its band where the separation gives one)`, num: true, get: (d) => d.stiffness_loss_pct, show: lossOf },
  { key: "trend_mm_per_month", label: "Trend (mm/mo)", title: "Depth trend, mm per month (— until two runs, or two successive separations, saw the defect)", num: true, get: (d) => trendOf(d, "trend_mm_per_month"), show: (d) => signed(trendOf(d, "trend_mm_per_month"), 3) },
  { key: "trend_loss_pct_per_month", label: "Trend (%/mo)", title: "Stiffness-loss trend, percentage points per month (— until two runs, or two successive separations, saw the defect)", num: true, get: (d) => trendOf(d, "trend_loss_pct_per_month"), show: (d) => signed(trendOf(d, "trend_loss_pct_per_month"), 1) },
  { key: "first_seen", label: "First seen", get: (d) => d.first_seen || "", show: (d) => fmtDay(d.first_seen) },
  { key: "last_seen", label: "Last seen", get: (d) => d.last_seen || "", show: (d) => fmtDay(d.last_seen) },
];

/** Shading of each defect on a chainage plot, by level (layout.shapes). */
export function defectShapes(defects) {
  return defects.map((d) => {
    const s = LEVEL_STYLE[d.level || "none"];
    return {
      type: "rect", xref: "x", yref: "paper", x0: d.start_m, x1: d.end_m, y0: 0, y1: 1,
      fillcolor: s.fill, line: { color: s.line, width: 1, dash: s.dash }, layer: "below", name: "defect",
    };
  });
}

/** Traces of the aggregated profile: the robust spread as a band around the median line. */
export function aggregateTraces(agg) {
  if (!agg || !Array.isArray(agg.chainage_m) || agg.chainage_m.length === 0) return [];
  const x = agg.chainage_m;
  const lv = agg.level_mm;
  const sp = agg.spread_mm || lv.map(() => 0);
  const hover = x.map((_, i) => [sp[i], agg.n_runs ? agg.n_runs[i] : null]);
  return [
    {
      type: "scatter", mode: "lines", x, y: lv.map((v, i) => v + sp[i]), meta: "aggregate-band-upper",
      line: { width: 0, color: "rgba(0,114,178,0)" }, hoverinfo: "skip", showlegend: false,
    },
    {
      type: "scatter", mode: "lines", x, y: lv.map((v, i) => v - sp[i]), meta: "aggregate-band",
      name: "Spread of the runs (±1.4826 MAD)", fill: "tonexty", fillcolor: "rgba(86, 180, 233, 0.35)",
      line: { width: 0, color: "rgba(86,180,233,0)" }, hoverinfo: "skip",
    },
    {
      type: "scatter", mode: "lines", x, y: lv, meta: "aggregate", name: "Aggregated profile (median)",
      line: { color: COLORS.truth, width: 2 }, customdata: hover,
      hovertemplate: "%{x:.2f} m: %{y:.3f} mm ± %{customdata[0]:.3f}, %{customdata[1]} runs<extra>aggregate</extra>",
    },
  ];
}

/** The card with the aggregated profile of the whole track (thinned server-side). */
export async function aggregateCard(enc, defects) {
  const div = h("div", { class: "plot plot-aggregate", id: "aggregate-plot", role: "figure", "aria-label": "Aggregated profile of the track: median level of the aligned runs with their spread, defects shaded by level" });
  const note = h("p", { class: "hint", id: "aggregate-note" });
  const section = h("section", { class: "card", "aria-labelledby": "aggregate-h" },
    h("h2", { id: "aggregate-h" }, "Aggregated profile"),
    h("p", { class: "hint" }, "Median loaded level of all aligned runs per 0.25 m, with their spread as a band; defects of the register shaded by level (solid: immediate action, dashed: intervention, dotted: alert)."),
    div, note);
  const render = async () => {
    let agg;
    try {
      agg = await apiFetch(`/api/v1/tracks/${enc}/profile?max_points=6000`);
    } catch (err) {
      note.textContent = `Cannot load the aggregated profile: ${err.message}`;
      return;
    }
    if (!agg.n) {
      note.textContent = "No aligned run yet: the aggregated profile is empty.";
      div.hidden = true;
      return;
    }
    div.hidden = false;
    const layout = baseLayout({
      height: 340, shapes: defectShapes(defects()), hovermode: "closest",
      margin: { l: 64, r: 16, t: 16, b: 52 }, legend: { orientation: "h", x: 0, y: 1.12 },
    });
    await (await loadPlotly()).react(div, aggregateTraces(agg), layout, CONFIG);
    note.textContent = `${agg.n.toLocaleString()} grid points${agg.decimated ? `, drawn as ${agg.chainage_m.length.toLocaleString()} (each stretch's lowest and highest point)` : ""}; up to ${plural(Math.max(...agg.n_runs), "run")} per point.`;
  };
  return { section, render };
}

/** Export links: the register (CSV, JSON), the aggregated profile (CSV), the report. */
export function exportLinks(enc, trackId) {
  const link = (id, href, text, download) => h("a", { class: "button small", id, href, download }, text);
  return h("div", { class: "downloads", id: "track-exports", role: "group", "aria-label": "Exports" },
    link("export-defects-csv", `/api/v1/tracks/${enc}/defects?format=csv`, "Defects (CSV)", `track-${trackId}-defects.csv`),
    link("export-defects-json", `/api/v1/tracks/${enc}/defects?include=history`, "Defects (JSON)", `track-${trackId}-defects.json`),
    link("export-profile-csv", `/api/v1/tracks/${enc}/profile?format=csv`, "Aggregated profile (CSV)", `track-${trackId}-profile.csv`),
    h("a", { class: "button small", id: "export-report", href: `/api/v1/tracks/${enc}/report`, target: "_blank", rel: "noopener" }, "Report (HTML)"),
  );
}

function isoDay(d) {
  const pad = (n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}`;
}

/** Alerts: the defects whose current level was reached since a chosen date. */
export function alertsCard(enc, getDefects = null) {
  const input = h("input", { type: "date", id: "alerts-since", required: true, value: isoDay(new Date(Date.now() - 30 * 86400e3)) });
  const button = h("button", { type: "submit", class: "button", id: "alerts-show" }, "Show alerts");
  const out = h("div", { id: "alerts-out", "aria-live": "polite" });
  const form = h("form", { class: "alerts-form", id: "alerts-form" },
    field("Since (date)", input, "Defects that reached their current limit level on or after this date (by recording date)."),
    h("div", { class: "actions" }, button));
  const section = h("section", { class: "card", "aria-labelledby": "alerts-h" },
    h("h2", { id: "alerts-h" }, "Alerts since a date"), form, out);
  const load = async () => {
    clear(out);
    const since = input.value;
    if (!since) {
      out.append(h("p", { class: "message error", role: "alert" }, "Choose a date."));
      return;
    }
    let alerts;
    try {
      alerts = await apiFetch(`/api/v1/tracks/${enc}/alerts?since=${encodeURIComponent(since)}`);
    } catch (err) {
      out.append(h("p", { class: "message error", role: "alert" }, `Cannot load the alerts: ${err.message}`));
      return;
    }
    if (!alerts.length) {
      // "No defect reached a limit" would read as "nothing to do" above defects at a limit
      // reached before the date: say those too.
      const atLimit = (getDefects ? getDefects() : []).filter((d) => d.level);
      const earlier = atLimit.length
        ? ` ${atLimit.length === 1 ? "One defect is" : `${atLimit.length} defects are`} at a limit reached before that (${["immediate", "intervention", "alert"].map((lv) => [lv, atLimit.filter((d) => d.level === lv).length]).filter(([, n]) => n).map(([lv, n]) => `${n} ${LEVEL_LABELS[lv].toLowerCase()}`).join(", ")}): see the defect register.`
        : "";
      out.append(h("p", { class: atLimit.length ? "message warning" : "muted", id: "alerts-none" }, `No defect reached a new limit level since ${since}.${earlier}`));
      announce(`No new alerts since ${since}.${earlier}`);
      return;
    }
    const rows = alerts.map((d) => h("tr", {},
      h("td", { class: "num" }, String(d.priority)),
      h("td", { class: `level level-${d.level}` }, LEVEL_LABELS[d.level] || d.level),
      h("td", {}, fmtDay(d.level_since)),
      h("td", { class: "num" }, fmtKmRange(d.start_m, d.end_m)),
      h("td", { class: "num" }, fmt(d.depth_mm, 2)),
      h("td", { class: "num" }, lossOf(d)),
      h("td", {}, d.status),
      h("td", {}, evidenceOf(d), provisionalLabel(d))));
    out.append(
      h("p", { class: "small", id: "alerts-count" }, `${alerts.length} defect${alerts.length === 1 ? "" : "s"} reached a limit since ${since}.`),
      scrollTable(`Alerts since ${since}`, h("table", { class: "data", id: "alerts-table" },
        h("caption", { class: "visually-hidden" }, `Defects that reached a limit since ${since}`),
        h("thead", {}, h("tr", {}, [["Priority", 1], ["Level"], ["Since"], ["Zone", 1], ["Depth (mm)", 1], ["Loss (%)", 1], ["Status"], ["Evidence"]].map(([t, num]) => h("th", { scope: "col", class: num ? "num" : null }, t)))),
        h("tbody", {}, rows))),
      h("a", { class: "button small", href: `/api/v1/tracks/${enc}/alerts?since=${encodeURIComponent(since)}&format=csv`, download: "alerts.csv" }, "These alerts (CSV)"));
    announce(`${alerts.length} alerts since ${since}.`);
  };
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    load();
  });
  return { section, load, input };
}

const LIMIT_FIELDS = [
  { key: "alert_depth_mm", label: "Alert depth (mm)", level: "alert" },
  { key: "intervention_depth_mm", label: "Intervention depth (mm)", level: "intervention" },
  { key: "immediate_depth_mm", label: "Immediate-action depth (mm)", level: "immediate" },
  { key: "alert_loss_pct", label: "Alert stiffness loss (%)", level: "alert" },
  { key: "intervention_loss_pct", label: "Intervention stiffness loss (%)", level: "intervention" },
  { key: "immediate_loss_pct", label: "Immediate-action stiffness loss (%)", level: "immediate" },
];

/** The limits form: loads the track's limits, saves them with PUT, names a refused field. */
export function limitsCard(enc, onSaved) {
  const inputs = {};
  const fields = LIMIT_FIELDS.map((f) => {
    const input = h("input", { type: "number", id: `limit-${f.key}`, name: f.key, step: "any", inputmode: "decimal" });
    inputs[f.key] = input;
    return field(f.label, input);
  });
  const state = h("p", { class: "hint", id: "limits-state" });
  const msg = messageBox("info");
  msg.el.id = "limits-message";
  const save = h("button", { type: "submit", class: "button primary", id: "limits-save" }, "Save limits");
  const form = h("form", { id: "limits-form", novalidate: true },
    h("div", { class: "grid-3" }, fields),
    h("p", { class: "hint" }, "A defect reaches a level when its depth or its stiffness loss in the latest run reaches that value; leave a box empty to switch that criterion off. Values grow from alert to immediate action."),
    h("div", { class: "actions" }, save, msg.el));
  const section = h("section", { class: "card", "aria-labelledby": "limits-h" },
    h("h2", { id: "limits-h" }, "Limits"), state, form);

  const show = (lim) => {
    for (const f of LIMIT_FIELDS) {
      inputs[f.key].value = lim[f.key] === null || lim[f.key] === undefined ? "" : String(lim[f.key]);
      inputs[f.key].removeAttribute("aria-invalid");
    }
    state.textContent = lim.is_default ? "The default limits (this track has none of its own yet)." : `This track's limits, set ${fmtDay(lim.updated_at)}.`;
  };
  // the service's own bounds (e.g. > 0, loss at most 100 %), from its schema
  apiSchema().then((spec) => {
    const props = spec.components.schemas.LimitsUpdate.properties;
    for (const f of LIMIT_FIELDS) applyBounds(inputs[f.key], props[f.key]);
  }).catch(() => {});
  const load = async () => {
    try {
      show(await apiFetch(`/api/v1/tracks/${enc}/limits`));
    } catch (err) {
      state.textContent = `Cannot load the limits: ${err.message}`;
    }
  };
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clearFieldErrors(form);
    msg.hide();
    const body = {};
    const bad = [];
    for (const f of LIMIT_FIELDS) {
      const raw = inputs[f.key].value.trim();
      const problem = numberProblem(inputs[f.key]);
      if (problem) {
        showFieldError(inputs[f.key], problem);
        bad.push(inputs[f.key]);
      }
      body[f.key] = raw === "" ? null : Number(raw);
    }
    if (bad.length) {
      msg.show("Not saved: correct the marked values.", "error");
      bad[0].focus();
      return;
    }
    save.disabled = true;
    try {
      const lim = await apiFetch(`/api/v1/tracks/${enc}/limits`, {
        method: "PUT",
        headers: { "Content-Type": "application/json", Accept: "application/json" },
        body: JSON.stringify(body),
      });
      show(lim);
      msg.show("Limits saved; the register is ranked with them.", "success");
      announce("Limits saved.");
      await onSaved();
    } catch (err) {
      const marked = err instanceof ApiError ? showServerErrors(form, err) : [];
      msg.show(marked.length ? "Not saved: correct the marked values." : `Not saved: ${err.message}`, "error");
      if (marked.length) marked[0].focus();
    } finally {
      save.disabled = false;
    }
  });
  return { section, load };
}

const NOTICE_RUNS = 10; // runs named in a notice; the others counted

// What each alignment status (the API's RunAlignmentPublic.status) means for the track's
// register: a reference or an aligned run needs no word; the others are listed with why.
const ALIGNMENT_NOTES = {
  reference: null,
  aligned: null,
  placed: {
    id: "placed-runs",
    kind: "info",
    lead: (n) => `${n === 1 ? "1 run is" : `${n} runs are`} in the aggregated profile and the register at the chainage ${n === 1 ? "its log (or its GNSS fixes) gave" : "their logs (or their GNSS fixes) gave"}, not yet matched to the track's profile: ${n === 1 ? "its" : "their"} position is as uncertain as that start, and ${n === 1 ? "it is" : "they are"} aligned again as the track gains passes: `,
  },
  unaligned: {
    id: "unaligned-runs",
    kind: "warning",
    reasons: true,
    lead: (n) => `${n === 1 ? "1 run was" : `${n} runs were`} not aligned to this track and ${n === 1 ? "is" : "are"} left out of the aggregated profile and the register: `,
  },
};

/**
 * The notices of the track's runs whose alignment status needs a word (placed, unaligned, or
 * a status this page does not know), each listing its runs with the reason; null when every
 * run is a reference or aligned.
 */
export function alignmentNotice(runs) {
  const byStatus = new Map();
  for (const r of runs) {
    const st = r.alignment && r.alignment.status;
    if (!st || ALIGNMENT_NOTES[st] === null) continue;
    if (!byStatus.has(st)) byStatus.set(st, []);
    byStatus.get(st).push(r);
  }
  if (!byStatus.size) return null;
  const wrap = h("div", { id: "alignment-notices" });
  for (const [st, list] of byStatus) {
    const note = ALIGNMENT_NOTES[st] || {
      id: `${st}-runs`, kind: "warning", reasons: true, lead: (n) => `${n === 1 ? "1 run has" : `${n} runs have`} the alignment status “${st}”: `,
    };
    const shown = list.slice(0, NOTICE_RUNS);
    wrap.append(h("div", { class: `message ${note.kind}`, role: "status", id: note.id },
      note.lead(list.length),
      shown.map((r, i) => [i ? "; " : "", h("a", { href: `#/runs/${encodeURIComponent(r.id)}` }, `run ${r.id}`), note.reasons && r.alignment.reason ? ` (${r.alignment.reason})` : ""]),
      list.length > shown.length ? ` and ${list.length - shown.length} more` : "", "."));
  }
  return wrap;
}
