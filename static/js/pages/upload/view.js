// Upload page view: the form (file, columns and units, track/vehicle/position, upload), the
// preview of the file's first rows and the way errors are shown. No requests are made here.

import { h, clear, append, announce, field, fmt, messageBox, scrollTable } from "../../dom.js";
import { ApiError } from "../../api.js";
import { estimateRate, HEAD_BYTES } from "../../csvpreview.js";
import { applyBounds } from "../../formerrors.js";
import { GRAVITY_TEXT, currentRecognition, effectiveReading, roleOf } from "./state.js";

/** Build the form into `main`; returns the elements the actions work with. */
export function buildForm(main, state) {
  const ui = {};
  main.appendChild(h("p", { class: "lead" },
    "Drop a logger file (CSV, optionally gzip-compressed). Check that the columns were recognised, say on which track the run was recorded and where on it the log starts, and upload. The loaded profile and its soft spots are ready a few seconds later."));
  main.appendChild(h("p", { class: "hint", id: "example-hint" },
    "No log at hand? The repository ships one: examples/example_run.csv.gz (start chainage 24.13 m, increasing; its truth is in examples/example_run.truth.json)."));

  const form = h("form", { class: "upload-form", novalidate: true, "aria-describedby": "upload-status" });
  ui.form = form;
  main.appendChild(form);

  // ---- 1. File -------------------------------------------------------------------------------
  // The native input stays in the tab order (visually hidden); its label is the visible button.
  ui.fileInput = h("input", { type: "file", id: "file-input", name: "file", class: "visually-hidden", accept: ".csv,.txt,.gz,.tsv,text/csv,application/gzip" });
  ui.fileInfo = h("p", { class: "file-info", id: "file-info", "aria-live": "polite" }, "No file chosen yet.");
  ui.dropZone = h("div", { class: "drop-zone", id: "drop-zone" },
    h("p", { class: "drop-title" }, "Drag and drop a run log here"),
    h("p", {}, "or"),
    ui.fileInput,
    h("label", { for: "file-input", class: "button secondary" }, "Choose a file…"),
    ui.fileInfo,
  );
  ui.previewBox = h("div", { class: "preview", id: "csv-preview" });
  form.appendChild(h("fieldset", { class: "card" },
    h("legend", {}, "1. Run log file"),
    ui.dropZone,
    ui.previewBox,
  ));

  // ---- 2. Columns and units ------------------------------------------------------------------
  const mappingGrid = h("div", { class: "mapping-grid", id: "mapping" });
  ui.selects = {};
  for (const role of state.roles) {
    const colSel = h("select", { name: role.column, id: `map-${role.key}-column`, "data-role": role.key });
    colSel.appendChild(h("option", { value: "" }, "Automatic"));
    const parts = [field(`${role.label} column`, colSel)];
    let unitSel = null;
    if (role.unit) {
      unitSel = h("select", { name: role.unit, id: `map-${role.key}-unit` });
      unitSel.appendChild(h("option", { value: "" }, "Automatic"));
      for (const u of role.units) unitSel.appendChild(h("option", { value: u }, role.unitLabels[u]));
      parts.push(field(`${role.label} unit`, unitSel));
    }
    ui.selects[role.key] = { colSel, unitSel };
    mappingGrid.appendChild(h("div", { class: "mapping-row" }, parts));
  }
  ui.gravitySel = h("select", { name: "gravity", id: "map-gravity" },
    h("option", { value: "" }, "Automatic"),
    state.gravityModes.map((g) => h("option", { value: g }, GRAVITY_TEXT[g] || g)),
  );
  mappingGrid.appendChild(h("div", { class: "mapping-row" }, field("Gravity in the acceleration", ui.gravitySel)));
  ui.recognisedNote = h("p", { class: "hint", id: "recognised-note" }, "Choose a file to see which columns are recognised.");
  form.appendChild(h("fieldset", { class: "card" },
    h("legend", {}, "2. Columns and units"),
    ui.recognisedNote,
    mappingGrid,
  ));

  // ---- 3. Where and when ---------------------------------------------------------------------
  ui.trackInput = h("input", { type: "text", name: "track", id: "track-input", list: "track-list", required: true, autocomplete: "off", maxlength: 200 });
  ui.trackList = h("datalist", { id: "track-list" });
  ui.newTrackBox = h("div", { class: "new-track", hidden: true });
  // Sent with the upload and stored with the run (one transaction: a rejected upload leaves
  // no track behind).
  ui.trackDesc = h("input", { type: "text", id: "track-description", name: "track_description", maxlength: 500 });
  ui.trackK = h("input", { type: "number", id: "track-k", name: "track_k_nominal", value: "80", step: "any" });
  ui.trackSpacing = h("input", { type: "number", id: "track-spacing", name: "track_spacing", value: "0.6", step: "any" });
  ui.trackRail = h("input", { type: "text", id: "track-rail", name: "track_rail", value: "UIC60", maxlength: 50 });
  applyBounds(ui.trackK, state.props.track_k_nominal, 1e6); // kN/mm shown, N/m sent
  applyBounds(ui.trackSpacing, state.props.track_spacing);
  append(ui.newTrackBox, [
    h("p", { class: "hint" }, "New track: it is created with these details when you upload."),
    h("div", { class: "grid-2" },
      field("Description", ui.trackDesc),
      field("Rail", ui.trackRail),
      field("Nominal support stiffness (kN/mm)", ui.trackK),
      field("Sleeper spacing (m)", ui.trackSpacing)),
  ]);

  ui.vehicleSel = h("select", { name: "vehicle", id: "vehicle-select", "aria-describedby": "vehicle-why" });
  ui.vehicleHint = h("p", { class: "hint", id: "vehicle-why", "aria-live": "polite" });
  ui.vehicleMsg = messageBox("info");
  ui.vehicleInputs = {};
  ui.vehicleName = h("input", { type: "text", id: "vehicle-name", maxlength: 200 });
  const vehicleForm = h("div", { class: "grid-3" }, field("Name", ui.vehicleName));
  for (const [key, label, unit, def] of state.vehicleFields) {
    const input = h("input", { type: "number", id: `veh-${key}`, name: key, value: String(def), step: "any" });
    applyBounds(input, state.vehicleProps[key]);
    ui.vehicleInputs[key] = input;
    vehicleForm.appendChild(field(`${label} (${unit})`, input));
  }
  ui.createVehicleBtn = h("button", { type: "button", class: "button secondary", id: "create-vehicle" }, "Create vehicle");
  const vehicleDetails = h("details", { class: "new-vehicle", id: "new-vehicle" },
    h("summary", {}, "Create a vehicle (half-car parameters)"),
    vehicleForm, ui.createVehicleBtn, ui.vehicleMsg.el);
  ui.vehicleDetails = vehicleDetails;

  // Empty and required: a start chainage guessed as 0 puts every result tens of metres off
  // without a word. Optional only when the run can be placed otherwise (canPlaceWithoutStart).
  ui.startInput = h("input", { type: "number", name: "start_chainage_m", id: "start-chainage", step: "any", required: true, placeholder: "e.g. 1234.5" });
  ui.directionSel = h("select", { name: "direction", id: "direction" },
    h("option", { value: "increasing" }, "Increasing chainage"),
    h("option", { value: "decreasing" }, "Decreasing chainage"));
  ui.recordedInput = h("input", { type: "datetime-local", name: "recorded_at", id: "recorded-at" });
  ui.recordedInput.addEventListener("input", () => {
    ui.recordedInput.dataset.userSet = "1";
  });
  // What the log cannot know about the wheel force (issue 10): the payload carried, or the
  // static wheel load measured; runs of different loads let the track separate geometry from
  // stiffness. Both blank: the registered vehicle's own load.
  ui.payloadInput = h("input", { type: "number", name: "payload_kg", id: "payload-kg", step: "any", placeholder: "none" });
  ui.wheelLoadInput = h("input", { type: "number", name: "static_wheel_load_n", id: "static-wheel-load", step: "any", placeholder: "from the vehicle" });
  applyBounds(ui.payloadInput, state.props.payload_kg);
  applyBounds(ui.wheelLoadInput, state.props.static_wheel_load_n);

  form.appendChild(h("fieldset", { class: "card" },
    h("legend", {}, "3. Track, vehicle and position"),
    h("div", { class: "grid-2" },
      h("div", {}, field("Track", ui.trackInput, "Pick an existing track or type a new name."), ui.trackList),
      h("div", {}, field("Vehicle", ui.vehicleSel), ui.vehicleHint),
      field("Start chainage (m)", ui.startInput, "Where on the track the log starts: the chainage (distance along the line, m) of the body centre (the IMU) at the first sample. Required unless the file has a chainage column."),
      field("Direction of travel", ui.directionSel),
      field("Recorded at (local time)", ui.recordedInput, "Taken from the file's timestamps when it has them; otherwise give it (else the upload time is stored)."),
      field("Payload (kg)", ui.payloadInput, "Load carried on top of the vehicle's own mass (passengers, freight)."),
      field("Measured static wheel load (N)", ui.wheelLoadInput, "Instead of the payload, if a load-weigh system measured it."),
    ),
    ui.newTrackBox,
    vehicleDetails,
  ));

  // ---- 4. Upload -----------------------------------------------------------------------------
  ui.submitBtn = h("button", { type: "submit", class: "button primary", id: "upload-button" }, "Upload and process");
  ui.uploadBar = h("progress", { id: "upload-progress", max: "1", value: "0", "aria-label": "Upload progress" });
  ui.processBar = h("progress", { id: "process-progress", max: "1", "aria-label": "Processing progress" });
  ui.uploadLabel = h("span", { class: "progress-label" }, "Upload");
  ui.processLabel = h("span", { class: "progress-label" }, "Processing");
  ui.progressBox = h("div", { class: "progress-box", hidden: true },
    h("div", { class: "progress-row" }, ui.uploadLabel, ui.uploadBar),
    h("div", { class: "progress-row" }, ui.processLabel, ui.processBar));
  ui.ignoreProblems = h("input", { type: "checkbox", id: "ignore-problems" });
  ui.ignoreBox = h("label", { class: "check", hidden: true, id: "ignore-problems-label" }, ui.ignoreProblems, " Upload anyway, despite the problems the preview found");
  ui.status = messageBox("info");
  ui.status.el.id = "upload-status";
  form.appendChild(h("div", { class: "card actions" }, ui.ignoreBox, ui.submitBtn, ui.progressBox, ui.status.el));
  return ui;
}

/** The problems the preview found (the service's reading of the file's head). */
export function previewProblems(state) {
  const p = state.preview;
  if (!p || !p.serverNow) return [];
  const problems = [];
  if (p.serverNow.error) {
    const d = p.serverNow.error;
    problems.push(typeof d === "string" ? d : d.message || JSON.stringify(d));
  }
  const server = p.serverNow.answer;
  if (server && Array.isArray(server.warnings)) problems.push(...server.warnings);
  return problems;
}

/** The start chainage required, or optional when the run can be placed otherwise. */
export function showStartRequired(ui, canPlace) {
  if (ui.startInput.required === !canPlace) return; // no DOM change: observers stay quiet
  ui.startInput.required = !canPlace;
  const startLabel = ui.form.querySelector('label[for="start-chainage"]');
  if (startLabel) startLabel.textContent = canPlace ? "Start chainage (m, optional)" : "Start chainage (m)";
}

/** Start chainage required or not, the recording time from the file, the upload guard. */
export function showPlacement(ui, state, { recordedAt, canPlace }) {
  showStartRequired(ui, canPlace);
  const hint = document.getElementById("recorded-at-hint");
  if (recordedAt) {
    if (!ui.recordedInput.dataset.userSet) ui.recordedInput.value = recordedAt.local;
    hint.textContent = `From the file's timestamps: ${recordedAt.text}. Change it if it is wrong.`;
    hint.className = "hint";
  } else {
    hint.textContent = "The file has no clock time (its times count from the start): give when it was recorded, otherwise the upload time is stored.";
    hint.className = "hint warning-text";
  }
  const problems = previewProblems(state);
  ui.ignoreBox.hidden = problems.length === 0;
  if (!problems.length) ui.ignoreProblems.checked = false;
}

/** The two progress bars after a failure: the failed step says so, the other is idle. */
export function markFailed(ui, step) {
  ui.progressBox.classList.add("failed");
  if (step === "upload") {
    ui.uploadLabel.textContent = "Upload failed";
    ui.uploadBar.classList.add("failed");
    ui.processLabel.textContent = "Processing not started";
    ui.processBar.value = 0;
  } else {
    ui.processLabel.textContent = "Processing failed";
    ui.processBar.classList.add("failed");
    ui.processBar.value = 1;
  }
}

export function resetProgress(ui) {
  ui.progressBox.classList.remove("failed");
  ui.uploadBar.classList.remove("failed");
  ui.processBar.classList.remove("failed");
}

/** Fill the track and vehicle choices (keeps the chosen vehicle). */
export function showChoices(ui, state) {
  clear(ui.trackList);
  for (const t of state.tracks) ui.trackList.appendChild(h("option", { value: t.name }));
  clear(ui.vehicleSel);
  ui.vehicleSel.appendChild(h("option", { value: "" }, "Choose the vehicle…"));
  const names = state.vehicles.map((v) => v.name);
  for (const name of names) ui.vehicleSel.appendChild(h("option", { value: name }, name));
  // the engine's presets not stored yet are choices too (stored on first use); table1 always
  for (const name of state.presets || [DEFAULT_VEHICLE]) {
    if (!names.includes(name)) ui.vehicleSel.appendChild(h("option", { value: name }, `${name} (preset)`));
  }
  pickVehicle(ui, state);
}

export const DEFAULT_VEHICLE = "table1";

/**
 * The vehicle the form proposes, said next to it — never a silent choice: the user's own
 * choice; else the vehicle of most of the track's runs; else table1 when it is the only
 * candidate; else none, and the form asks (several vehicles and nothing to tell them apart).
 */
export function pickVehicle(ui, state) {
  const track = ui.trackInput.value.trim();
  const usual = state.usualVehicle ? state.usualVehicle[track] : undefined;
  const others = state.vehicles.filter((v) => v.name !== DEFAULT_VEHICLE);
  let value = "";
  let why;
  if (state.vehicleChosen && ui.vehicleSel.querySelector(`option[value="${CSS.escape(state.vehicleChosen)}"]`)) {
    value = state.vehicleChosen;
    why = "Your choice.";
  } else if (usual) {
    value = usual;
    why = `The vehicle of most runs on track “${track}”: check it recorded this log.`;
  } else if (others.length === 0) {
    value = DEFAULT_VEHICLE;
    why = `The default vehicle (${DEFAULT_VEHICLE}, the Table 1 passenger coach): the only one registered.`;
  } else {
    const mixed = state.mixedVehicles ? state.mixedVehicles[track] : null;
    const reason = mixed ? `this track's runs are as many of ${mixed.join(" as of ")}` : track ? "this track has no runs yet" : "no track is chosen";
    why = `${others.length + 1} vehicles are registered and ${reason}: choose the vehicle that recorded this log (its wheel load matters).`;
  }
  ui.vehicleSel.value = value;
  ui.vehicleHint.textContent = why;
}

/** The new-track details show when the typed name is not an existing track. */
export function updateNewTrack(ui, state) {
  const name = ui.trackInput.value.trim();
  ui.newTrackBox.hidden = !name || state.tracks.some((t) => t.name === name);
}

export function showPreviewMessage(ui, text, kind = "muted") {
  clear(ui.previewBox);
  const attrs = kind === "error" ? { class: "message error", role: "alert" } : { class: kind };
  ui.previewBox.appendChild(h("p", attrs, text));
}

function unitLabel(role, unit) {
  return role.unitLabels[unit] || unit;
}

/** The preview table with its column badges, the problems found and the mapping choices. */
export function showPreview(ui, state) {
  const { roles, file } = state;
  const { parsed, head } = state.preview;
  const server = state.preview.serverNow && state.preview.serverNow.answer ? state.preview.serverNow.answer : null;
  const rec = currentRecognition(state);
  const eff = effectiveReading(state);
  const { previewBox, selects, gravitySel, recognisedNote } = ui;
  clear(previewBox);
  const columns = server ? server.columns : parsed.columns;
  const rows = server ? server.rows : parsed.rows.slice(0, 10);
  if (columns.length === 0) {
    previewBox.appendChild(h("p", { class: "message error", role: "alert" }, "The file looks empty: no header line found."));
    return;
  }
  const delim = server ? server.delimiter : parsed.delimiter;
  const delimName = { ",": "comma", ";": "semicolon", "\t": "tab", " ": "space" }[delim] || delim;
  const rate = eff.mapping.time ? estimateRate(parsed, eff.mapping.time.column, eff.mapping.time.unit) : null;
  const facts = [
    `${columns.length} columns`, `${delimName}-separated`, head.gzip ? "gzip-compressed" : null,
    rate ? `about ${fmt(rate, rate >= 100 ? 0 : 1)} Hz` : null,
    rate && head.complete ? `${fmt(parsed.rows.length / rate, 1)} s long` : null,
    rate && !head.complete && !head.gzip && file ? `about ${fmt((file.size / (HEAD_BYTES / Math.max(parsed.rows.length, 1))) / rate, 0)} s long` : null,
  ].filter(Boolean);
  previewBox.appendChild(h("p", { class: "hint" }, `First rows (${facts.join(", ")}):`));
  const thead = h("tr", {});
  for (const c of columns) {
    const role = roleOf(c, eff);
    const roleLabel = role ? roles.find((r) => r.key === role).label.replace(" (optional)", "") : null;
    const unit = role && eff.mapping[role] ? eff.mapping[role].unit : null;
    thead.appendChild(h("th", { scope: "col" }, c,
      roleLabel ? h("span", { class: "badge" }, unit ? `${roleLabel}, ${unit}` : roleLabel) : null));
  }
  const tbody = h("tbody", {});
  for (const r of rows.slice(0, 10)) tbody.appendChild(h("tr", {}, r.map((cell) => h("td", {}, String(cell)))));
  previewBox.appendChild(scrollTable("Preview of the first rows",
    h("table", { class: "data preview-table", id: "preview-table" }, h("thead", {}, thead), tbody)));
  const problems = previewProblems(state);
  if (problems.length) {
    previewBox.appendChild(h("div", { class: "message warning", role: "status", id: "preview-warnings" },
      "Check before uploading:", h("ul", {}, problems.map((p) => h("li", {}, p)))));
  }
  // Fill the mapping selects with the file's columns; keep the user's explicit choices.
  for (const role of roles) {
    const { colSel, unitSel } = selects[role.key];
    const chosen = colSel.value;
    clear(colSel);
    const auto = rec.mapping[role.key];
    colSel.appendChild(h("option", { value: "" }, auto ? `Automatic: ${auto.column}` : "Automatic (not recognised)"));
    for (const c of columns) colSel.appendChild(h("option", { value: c }, c));
    if (chosen && columns.includes(chosen)) colSel.value = chosen;
    if (unitSel) {
      unitSel.options[0].textContent = auto && auto.unit ? `Automatic: ${unitLabel(role, auto.unit)}` : "Automatic";
    }
  }
  gravitySel.options[0].textContent = rec.gravity ? `Automatic: ${rec.gravity}` : "Automatic";
  const found = roles.filter((r) => eff.mapping[r.key]).map((r) => `${r.label.replace(" (optional)", "")} = ${eff.mapping[r.key].column}`);
  const missing = roles.filter((r) => !eff.mapping[r.key] && !r.optional && r.key !== "speed").map((r) => r.label);
  recognisedNote.textContent = (eff.source === "server"
    ? `Recognised by the service: ${found.join("; ") || "nothing"}.`
    : "The service could not be asked to read the file.")
    + (missing.length ? ` Not recognised: ${missing.join(", ")} — choose the columns below.` : " Change a choice below if it is wrong.");
  recognisedNote.className = missing.length ? "message warning" : "hint";
  announce(`Preview ready: ${columns.length} columns.`);
}

export function errorText(err) {
  if (err instanceof ApiError) {
    const prefix = err.status === 413 ? "The file is too large. " : "";
    return `${prefix}${err.message}`;
  }
  return err.message || String(err);
}

export function errorList(err, words = (t) => t) {
  if (!(err instanceof ApiError) || !err.items || err.items.length === 0) return [];
  return [h("ul", { class: "error-facts" }, err.items.map((i) => h("li", {}, words(i))))];
}

/** Mark the fields an error names (by form name, or the column the file's reader named). */
export function highlightFields(ui, state, err) {
  for (const el of ui.form.querySelectorAll("[aria-invalid]")) el.removeAttribute("aria-invalid");
  if (!(err instanceof ApiError)) return;
  const names = [...(err.fields || [])];
  const column = err.detail && typeof err.detail === "object" && !Array.isArray(err.detail) ? err.detail.column : null;
  if (column) {
    for (const role of state.roles) {
      const rec = currentRecognition(state);
      const chosen = ui.selects[role.key].colSel.value || (rec.mapping[role.key] && rec.mapping[role.key].column);
      if (chosen === column) names.push(role.column);
    }
  }
  for (const name of names) {
    const el = ui.form.querySelector(`[name="${CSS.escape(name)}"]`);
    if (el) el.setAttribute("aria-invalid", "true");
  }
}

/** The column/row/unit facts of a stored run error, as a list (or null). */
export function errorFactsOfRun(error) {
  if (!error || typeof error !== "object") return null;
  const facts = [];
  for (const key of ["column", "row", "unit"]) {
    if (error[key] !== undefined && error[key] !== null) facts.push(`${key[0].toUpperCase()}${key.slice(1)}: ${error[key]}`);
  }
  return facts.length ? h("ul", { class: "error-facts" }, facts.map((f) => h("li", {}, f))) : null;
}
