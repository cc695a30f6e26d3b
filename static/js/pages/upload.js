// Upload page: choose or drop a log, check the preview and the column/unit mapping, say where
// the run was recorded, upload with progress, then follow processing until the run is ready.

import { h, clear, append, announce, field, fmt, messageBox } from "../dom.js";
import {
  ApiError, apiFetch, apiPostJson, apiSchema, uploadWithProgress,
} from "../api.js";
import { readHead, parseHead, estimateRate, HEAD_BYTES } from "../csvpreview.js";

// The vocabulary of this page comes from the service's OpenAPI schema, which is derived from
// the engine's CsvOptions (column roles, their units) and VehicleParams (Table 1 defaults).
const GRAVITY_TEXT = {
  included: "Included (raw IMU, about +1 g at rest)",
  removed: "Removed (about 0 at rest)",
};

/** Column roles of the upload form: [{key, label, column, unit, units, unitLabels}]. */
function rolesOf(spec) {
  const props = spec.components.schemas.RunCreateJson.properties;
  const roles = [];
  for (const [name, p] of Object.entries(props)) {
    if (!name.endsWith("_column") || !p["x-role"]) continue;
    const key = p["x-role"];
    const unit = props[`${key}_unit`];
    const label = p["x-label"].charAt(0).toUpperCase() + p["x-label"].slice(1);
    roles.push({
      key, label: key === "chainage" ? `${label} (optional)` : label, column: name,
      unit: unit ? `${key}_unit` : null, units: unit ? unit["x-units"] : [],
      unitLabels: unit ? unit["x-unit-labels"] : {},
    });
  }
  return { roles, gravity: props.gravity["x-values"].filter((g) => g !== "auto") };
}

/** Vehicle parameters: [[name, label, unit, default]] (defaults: the Table 1 vehicle). */
function vehicleFieldsOf(spec) {
  const props = spec.components.schemas.VehicleParamsSchema.properties;
  return Object.entries(props).map(([name, p]) => {
    const cut = p.description.lastIndexOf(", ");
    return [name, p.description.slice(0, cut), p.description.slice(cut + 2), p.default];
  });
}

function nowLocalInput() {
  const d = new Date();
  d.setSeconds(0, 0);
  const pad = (n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}T${pad(d.getHours())}:${pad(d.getMinutes())}`;
}

function formatBytes(n) {
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${(n / 1024).toFixed(1)} KB`;
  return `${(n / 1024 / 1024).toFixed(1)} MB`;
}

export async function render(main) {
  let stopped = false;
  let pollTimer = null;
  let file = null;
  let preview = null; // {parsed, head, serverAuto, serverNow}

  main.appendChild(h("h1", {}, "Upload a run"));
  let ROLES;
  let GRAVITY_MODES;
  let VEHICLE_FIELDS;
  try {
    const spec = await apiSchema();
    ({ roles: ROLES, gravity: GRAVITY_MODES } = rolesOf(spec));
    VEHICLE_FIELDS = vehicleFieldsOf(spec);
  } catch (err) {
    main.appendChild(h("p", { class: "message error", role: "alert" }, `Cannot load the upload form: ${err.message}`));
    return null;
  }
  main.appendChild(h("p", { class: "lead" },
    "Drop a logger file (CSV, optionally gzip-compressed). Check that the columns were recognised, say on which track the run was recorded, and upload. The loaded profile and its soft spots are ready a few seconds later."));

  const form = h("form", { class: "upload-form", novalidate: true, "aria-describedby": "upload-status" });
  main.appendChild(form);

  // ---- 1. File -------------------------------------------------------------------------------
  // The native input stays in the tab order (visually hidden); its label is the visible button.
  const fileInput = h("input", { type: "file", id: "file-input", name: "file", class: "visually-hidden", accept: ".csv,.txt,.gz,.tsv,text/csv,application/gzip" });
  const fileInfo = h("p", { class: "file-info", id: "file-info", "aria-live": "polite" }, "No file chosen yet.");
  const dropZone = h("div", { class: "drop-zone", id: "drop-zone" },
    h("p", { class: "drop-title" }, "Drag and drop a run log here"),
    h("p", {}, "or"),
    fileInput,
    h("label", { for: "file-input", class: "button secondary" }, "Choose a file…"),
    fileInfo,
  );
  const previewBox = h("div", { class: "preview", id: "csv-preview" });
  form.appendChild(h("fieldset", { class: "card" },
    h("legend", {}, "1. Run log file"),
    dropZone,
    previewBox,
  ));

  // ---- 2. Columns and units ------------------------------------------------------------------
  const mappingGrid = h("div", { class: "mapping-grid", id: "mapping" });
  const selects = {};
  for (const role of ROLES) {
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
    selects[role.key] = { colSel, unitSel };
    mappingGrid.appendChild(h("div", { class: "mapping-row" }, parts));
  }
  const gravitySel = h("select", { name: "gravity", id: "map-gravity" },
    h("option", { value: "" }, "Automatic"),
    GRAVITY_MODES.map((g) => h("option", { value: g }, GRAVITY_TEXT[g] || g)),
  );
  mappingGrid.appendChild(h("div", { class: "mapping-row" }, field("Gravity in the acceleration", gravitySel)));
  const recognisedNote = h("p", { class: "hint", id: "recognised-note" }, "Choose a file to see which columns are recognised.");
  form.appendChild(h("fieldset", { class: "card" },
    h("legend", {}, "2. Columns and units"),
    recognisedNote,
    mappingGrid,
  ));

  // ---- 3. Where and when ---------------------------------------------------------------------
  const trackInput = h("input", { type: "text", name: "track", id: "track-input", list: "track-list", required: true, autocomplete: "off", maxlength: 200 });
  const trackList = h("datalist", { id: "track-list" });
  const newTrackBox = h("div", { class: "new-track", hidden: true });
  const trackDesc = h("input", { type: "text", id: "track-description", maxlength: 500 });
  const trackK = h("input", { type: "number", id: "track-k", value: "80", min: "1", step: "any" });
  const trackSpacing = h("input", { type: "number", id: "track-spacing", value: "0.6", min: "0.1", step: "any" });
  const trackRail = h("input", { type: "text", id: "track-rail", value: "UIC60", maxlength: 50 });
  append(newTrackBox, [
    h("p", { class: "hint" }, "New track: it is created with these details when you upload."),
    h("div", { class: "grid-2" },
      field("Description", trackDesc),
      field("Rail", trackRail),
      field("Nominal support stiffness (kN/mm)", trackK),
      field("Sleeper spacing (m)", trackSpacing)),
  ]);

  const vehicleSel = h("select", { name: "vehicle", id: "vehicle-select" });
  const vehicleMsg = messageBox("info");
  const vehicleInputs = {};
  const vehicleName = h("input", { type: "text", id: "vehicle-name", maxlength: 200 });
  const vehicleForm = h("div", { class: "grid-3" }, field("Name", vehicleName));
  for (const [key, label, unit, def] of VEHICLE_FIELDS) {
    const input = h("input", { type: "number", id: `veh-${key}`, value: String(def), step: "any" });
    vehicleInputs[key] = input;
    vehicleForm.appendChild(field(`${label} (${unit})`, input));
  }
  const createVehicleBtn = h("button", { type: "button", class: "button secondary", id: "create-vehicle" }, "Create vehicle");
  const vehicleDetails = h("details", { class: "new-vehicle" },
    h("summary", {}, "Create a vehicle (half-car parameters)"),
    vehicleForm, createVehicleBtn, vehicleMsg.el);

  const startInput = h("input", { type: "number", name: "start_chainage_m", id: "start-chainage", value: "0", step: "any" });
  const directionSel = h("select", { name: "direction", id: "direction" },
    h("option", { value: "increasing" }, "Increasing chainage"),
    h("option", { value: "decreasing" }, "Decreasing chainage"));
  const recordedInput = h("input", { type: "datetime-local", name: "recorded_at", id: "recorded-at", value: nowLocalInput() });
  // What the log cannot know about the wheel force (issue 10): the payload carried, or the
  // static wheel load measured; runs of different loads let the track separate geometry from
  // stiffness. Both blank: the registered vehicle's own load.
  const payloadInput = h("input", { type: "number", name: "payload_kg", id: "payload-kg", min: "0", step: "any", placeholder: "none" });
  const wheelLoadInput = h("input", { type: "number", name: "static_wheel_load_n", id: "static-wheel-load", min: "0", step: "any", placeholder: "from the vehicle" });

  form.appendChild(h("fieldset", { class: "card" },
    h("legend", {}, "3. Track, vehicle and position"),
    h("div", { class: "grid-2" },
      h("div", {}, field("Track", trackInput, "Pick an existing track or type a new name."), trackList),
      field("Vehicle", vehicleSel),
      field("Start chainage (m)", startInput, "Chainage of the body centre (the IMU) at the first sample."),
      field("Direction of travel", directionSel),
      field("Recorded at (local time)", recordedInput),
      field("Payload (kg)", payloadInput, "Load carried on top of the vehicle's own mass (passengers, freight)."),
      field("Measured static wheel load (N)", wheelLoadInput, "Instead of the payload, if a load-weigh system measured it."),
    ),
    newTrackBox,
    vehicleDetails,
  ));

  // ---- 4. Upload -----------------------------------------------------------------------------
  const submitBtn = h("button", { type: "submit", class: "button primary", id: "upload-button" }, "Upload and process");
  const uploadBar = h("progress", { id: "upload-progress", max: "1", value: "0", "aria-label": "Upload progress" });
  const processBar = h("progress", { id: "process-progress", max: "1", "aria-label": "Processing progress" });
  const uploadLabel = h("span", { class: "progress-label" }, "Upload");
  const processLabel = h("span", { class: "progress-label" }, "Processing");
  const progressBox = h("div", { class: "progress-box", hidden: true },
    h("div", { class: "progress-row" }, uploadLabel, uploadBar),
    h("div", { class: "progress-row" }, processLabel, processBar));
  const status = messageBox("info");
  status.el.id = "upload-status";
  form.appendChild(h("div", { class: "card actions" }, submitBtn, progressBox, status.el));

  // ---- behaviour -----------------------------------------------------------------------------
  let tracks = [];
  let vehicles = [];

  async function loadChoices() {
    try {
      tracks = (await apiFetch("tracks")).data;
      clear(trackList);
      for (const t of tracks) trackList.appendChild(h("option", { value: t.name }));
    } catch (err) {
      status.show(`Could not load the tracks: ${err.message}`, "error");
    }
    try {
      vehicles = (await apiFetch("vehicles")).data;
      const previous = vehicleSel.value;
      clear(vehicleSel);
      for (const v of vehicles) vehicleSel.appendChild(h("option", { value: v.name }, v.name));
      if (previous) vehicleSel.value = previous;
    } catch (err) {
      status.show(`Could not load the vehicles: ${err.message}`, "error");
    }
  }

  function updateNewTrack() {
    const name = trackInput.value.trim();
    newTrackBox.hidden = !name || tracks.some((t) => t.name === name);
  }
  trackInput.addEventListener("input", updateNewTrack);

  createVehicleBtn.addEventListener("click", async () => {
    const name = vehicleName.value.trim();
    if (!name) {
      vehicleMsg.show("Give the vehicle a name.", "error");
      vehicleName.focus();
      return;
    }
    const params = {};
    for (const [key, input] of Object.entries(vehicleInputs)) {
      const v = Number(input.value);
      if (input.value === "" || !Number.isFinite(v)) {
        vehicleMsg.show(`${key} must be a number.`, "error");
        input.focus();
        return;
      }
      params[key] = v;
    }
    try {
      await apiPostJson("vehicles", { name, params });
      await loadChoices();
      vehicleSel.value = name;
      vehicleMsg.show(`Vehicle ${name} created and selected.`, "success");
    } catch (err) {
      vehicleMsg.show(errorText(err), "error", errorList(err));
    }
  });

  for (const ev of ["dragenter", "dragover"]) {
    dropZone.addEventListener(ev, (e) => {
      e.preventDefault();
      dropZone.classList.add("dragging");
    });
  }
  for (const ev of ["dragleave", "drop"]) {
    dropZone.addEventListener(ev, (e) => {
      e.preventDefault();
      dropZone.classList.remove("dragging");
    });
  }
  dropZone.addEventListener("drop", (e) => {
    const dropped = e.dataTransfer && e.dataTransfer.files && e.dataTransfer.files[0];
    if (dropped) chooseFile(dropped);
  });
  fileInput.addEventListener("change", () => {
    if (fileInput.files && fileInput.files[0]) chooseFile(fileInput.files[0]);
  });

  async function chooseFile(f) {
    file = f;
    status.hide();
    fileInfo.textContent = `${f.name} — ${formatBytes(f.size)}`;
    clear(previewBox);
    previewBox.appendChild(h("p", { class: "muted" }, "Reading the first rows…"));
    try {
      const head = await readHead(f);
      if (head.unsupported) {
        clear(previewBox);
        previewBox.appendChild(h("p", { class: "hint" }, "This browser cannot preview gzip files; the server will still read it."));
        return;
      }
      const parsed = parseHead(head.text, head.complete);
      preview = { parsed, head, serverAuto: null, serverNow: null };
      showPreview();
      // The engine's own reading of the head has the last word when the service answers.
      const server = await serverPreview(head.text, {});
      if (server && !stopped && file === f) {
        preview.serverAuto = server;
        preview.serverNow = server;
        showPreview();
        if (Object.keys(chosenOptions()).length) refreshServerPreview();
      }
    } catch (err) {
      clear(previewBox);
      previewBox.appendChild(h("p", { class: "message error", role: "alert" }, `Cannot preview this file: ${err.message}`));
    }
  }

  /** The column/unit options the user set explicitly (blank = automatic). */
  function chosenOptions() {
    const out = {};
    for (const role of ROLES) {
      const { colSel, unitSel } = selects[role.key];
      if (colSel.value) out[role.column] = colSel.value;
      if (unitSel && unitSel.value) out[role.unit] = unitSel.value;
    }
    if (gravitySel.value) out.gravity = gravitySel.value;
    return out;
  }

  async function serverPreview(text, options) {
    const cut = text.lastIndexOf("\n");
    const body = new Blob([cut > 0 ? text.slice(0, cut + 1) : text], { type: "text/csv" });
    const fd = new FormData();
    fd.append("file", body, "head.csv");
    for (const [k, v] of Object.entries(options)) fd.append(k, v);
    try {
      return { answer: await apiFetch("views/csv-preview", { method: "POST", body: fd }) };
    } catch (err) {
      // Unreachable or an older service without the preview: the page's own first look stays.
      if (!(err instanceof ApiError) || [0, 404, 405].includes(err.status)) return null;
      return { error: err.detail || { message: err.message } };
    }
  }

  let previewTimer = null;
  function refreshServerPreview() {
    if (!preview || !preview.serverAuto) return;
    clearTimeout(previewTimer);
    previewTimer = setTimeout(async () => {
      const f = file;
      const server = await serverPreview(preview.head.text, chosenOptions());
      if (server && !stopped && file === f) {
        preview.serverNow = server;
        showPreview();
      }
    }, 250);
  }
  for (const { colSel, unitSel } of Object.values(selects)) {
    colSel.addEventListener("change", refreshServerPreview);
    if (unitSel) unitSel.addEventListener("change", refreshServerPreview);
  }
  gravitySel.addEventListener("change", refreshServerPreview);

  /** A server preview as {mapping: role → {column, unit}, gravity}. */
  function fromServer(s) {
    const mapping = {};
    for (const role of ROLES) {
      const col = s.mapping ? s.mapping[role.key] : null;
      if (col) mapping[role.key] = { column: col, unit: s.units ? s.units[role.key] || null : null };
    }
    return { mapping, gravity: s.gravity || null, source: "server" };
  }

  /** What "Automatic" would pick: the service's reading without options (the page never
   * recognises columns itself: the engine's reader is the one authority). */
  function currentRecognition() {
    const s = preview && preview.serverAuto;
    if (s && s.answer) return fromServer(s.answer);
    return { mapping: {}, gravity: null, source: "none" };
  }

  /** How the file will be read with the current choices (for the column badges). */
  function effectiveReading() {
    const s = preview && preview.serverNow;
    if (s && s.answer) return fromServer(s.answer);
    return currentRecognition();
  }

  function roleOf(column, reading) {
    for (const [role, m] of Object.entries(reading.mapping)) if (m && m.column === column) return role;
    return null;
  }

  function showPreview() {
    const { parsed, head } = preview;
    const server = preview.serverNow && preview.serverNow.answer ? preview.serverNow.answer : null;
    const rec = currentRecognition();
    const eff = effectiveReading();
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
      const roleLabel = role ? ROLES.find((r) => r.key === role).label.replace(" (optional)", "") : null;
      const unit = role && eff.mapping[role] ? eff.mapping[role].unit : null;
      thead.appendChild(h("th", { scope: "col" }, c,
        roleLabel ? h("span", { class: "badge" }, unit ? `${roleLabel}, ${unit}` : roleLabel) : null));
    }
    const tbody = h("tbody", {});
    for (const r of rows.slice(0, 10)) tbody.appendChild(h("tr", {}, r.map((cell) => h("td", {}, String(cell)))));
    previewBox.appendChild(h("div", { class: "table-scroll", tabindex: "0", role: "region", "aria-label": "Preview of the first rows" },
      h("table", { class: "data preview-table", id: "preview-table" }, h("thead", {}, thead), tbody)));
    const problems = [];
    if (preview.serverNow && preview.serverNow.error) {
      const d = preview.serverNow.error;
      problems.push(typeof d === "string" ? d : d.message || JSON.stringify(d));
    }
    if (server && Array.isArray(server.warnings)) problems.push(...server.warnings);
    if (problems.length) {
      previewBox.appendChild(h("div", { class: "message warning", role: "status", id: "preview-warnings" },
        "Check before uploading:", h("ul", {}, problems.map((p) => h("li", {}, p)))));
    }
    // Fill the mapping selects with the file's columns; keep the user's explicit choices.
    for (const role of ROLES) {
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
    const found = ROLES.filter((r) => eff.mapping[r.key]).map((r) => `${r.label.replace(" (optional)", "")} = ${eff.mapping[r.key].column}`);
    const missing = ROLES.filter((r) => !eff.mapping[r.key] && !["chainage", "speed"].includes(r.key)).map((r) => r.label);
    recognisedNote.textContent = (eff.source === "server"
      ? `Recognised by the service: ${found.join("; ") || "nothing"}.`
      : "The service could not be asked to read the file.")
      + (missing.length ? ` Not recognised: ${missing.join(", ")} — choose the columns below.` : " Change a choice below if it is wrong.");
    recognisedNote.className = missing.length ? "message warning" : "hint";
    announce(`Preview ready: ${columns.length} columns.`);
  }

  function unitLabel(role, unit) {
    return role.unitLabels[unit] || unit;
  }

  function errorText(err) {
    if (err instanceof ApiError) {
      const prefix = err.status === 413 ? "The file is too large. " : "";
      return `${prefix}${err.message}`;
    }
    return err.message || String(err);
  }

  function errorList(err) {
    if (!(err instanceof ApiError) || !err.items || err.items.length === 0) return [];
    return [h("ul", { class: "error-facts" }, err.items.map((i) => h("li", {}, i)))];
  }

  function highlightFields(err) {
    for (const el of form.querySelectorAll("[aria-invalid]")) el.removeAttribute("aria-invalid");
    if (!(err instanceof ApiError)) return;
    const names = [...(err.fields || [])];
    const column = err.detail && typeof err.detail === "object" && !Array.isArray(err.detail) ? err.detail.column : null;
    if (column) {
      for (const role of ROLES) {
        const rec = currentRecognition();
        const chosen = selects[role.key].colSel.value || (rec.mapping[role.key] && rec.mapping[role.key].column);
        if (chosen === column) names.push(role.column);
      }
    }
    for (const name of names) {
      const el = form.querySelector(`[name="${CSS.escape(name)}"]`);
      if (el) el.setAttribute("aria-invalid", "true");
    }
  }

  async function ensureTrack(name) {
    if (tracks.some((t) => t.name === name)) return;
    const body = { name, rail: trackRail.value.trim() || "UIC60" };
    if (trackDesc.value.trim()) body.description = trackDesc.value.trim();
    const k = Number(trackK.value);
    const s = Number(trackSpacing.value);
    if (trackK.value !== "" && Number.isFinite(k)) body.k_nominal = k * 1e6; // kN/mm -> N/m
    if (trackSpacing.value !== "" && Number.isFinite(s)) body.spacing = s;
    try {
      await apiPostJson("tracks", body);
    } catch (err) {
      // A track created meanwhile (409) is fine: the upload names it.
      if (!(err instanceof ApiError && err.status === 409)) throw err;
    }
  }

  function poll(id, started) {
    return new Promise((resolve, reject) => {
      const tick = async () => {
        if (stopped) return;
        try {
          const run = await apiFetch(`runs/${encodeURIComponent(id)}`);
          const elapsed = (Date.now() - started) / 1000;
          if (typeof run.progress === "number") processBar.value = Math.max(0, Math.min(1, run.progress));
          processLabel.textContent = `Processing (${elapsed.toFixed(0)} s)`;
          if (run.status === "done") return resolve(run);
          if (run.status === "failed") return reject(Object.assign(new Error(runErrorMessage(run.error)), { run }));
          pollTimer = setTimeout(tick, 600);
        } catch (err) {
          reject(err);
        }
      };
      tick();
    });
  }

  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    status.hide();
    highlightFields(null);
    if (!file) {
      status.show("Choose a run log file first.", "error");
      fileInput.focus();
      return;
    }
    const track = trackInput.value.trim();
    if (!track) {
      status.show("Name the track the run was recorded on.", "error");
      trackInput.setAttribute("aria-invalid", "true");
      trackInput.focus();
      return;
    }
    if (startInput.value !== "" && !Number.isFinite(Number(startInput.value))) {
      status.show("The start chainage must be a number of metres.", "error");
      startInput.focus();
      return;
    }
    const fd = new FormData();
    fd.append("file", file, file.name);
    fd.append("track", track);
    if (vehicleSel.value) fd.append("vehicle", vehicleSel.value);
    if (startInput.value !== "") fd.append("start_chainage_m", startInput.value);
    fd.append("direction", directionSel.value);
    if (recordedInput.value) fd.append("recorded_at", new Date(recordedInput.value).toISOString());
    if (payloadInput.value !== "") fd.append("payload_kg", payloadInput.value);
    if (wheelLoadInput.value !== "") fd.append("static_wheel_load_n", wheelLoadInput.value);
    for (const role of ROLES) {
      const { colSel, unitSel } = selects[role.key];
      if (colSel.value) fd.append(role.column, colSel.value);
      if (unitSel && unitSel.value) fd.append(role.unit, unitSel.value);
    }
    if (gravitySel.value) fd.append("gravity", gravitySel.value);

    submitBtn.disabled = true;
    progressBox.hidden = false;
    uploadBar.value = 0;
    processBar.removeAttribute("value");
    uploadLabel.textContent = "Upload 0 %";
    processLabel.textContent = "Processing (waiting)";
    status.show("Uploading…", "info");
    try {
      await ensureTrack(track);
      const created = await uploadWithProgress("runs", fd, (frac) => {
        uploadBar.value = frac;
        uploadLabel.textContent = `Upload ${Math.round(frac * 100)} %`;
      });
      uploadBar.value = 1;
      uploadLabel.textContent = "Upload 100 %";
      const id = created.id;
      status.show(`Uploaded as run ${id}. Processing…`, "info");
      announce("Upload complete, processing the run.");
      const run = created.status === "done" ? created : await poll(id, Date.now());
      processBar.value = 1;
      processLabel.textContent = "Processing done";
      const link = h("a", { href: `#/runs/${encodeURIComponent(id)}`, id: "open-run" }, "Open the run");
      status.show(`Run ${id} processed. `, "success", [link]);
      announce(`Run ${id} processed.`);
      // Take the user straight to the result; the link stays for the back button.
      setTimeout(() => {
        if (!stopped) window.location.hash = `#/runs/${encodeURIComponent(run.id)}`;
      }, 400);
    } catch (err) {
      processBar.value = 0;
      const failedRun = err.run;
      if (failedRun) {
        processLabel.textContent = "Processing failed";
        const link = h("a", { href: `#/runs/${encodeURIComponent(failedRun.id)}` }, "See the run");
        status.show(`Processing failed: ${err.message} `, "error", [errorFactsOfRun(failedRun.error), link]);
      } else {
        status.show(errorText(err), "error", errorList(err));
        highlightFields(err);
      }
      announce("The upload failed.");
    } finally {
      submitBtn.disabled = false;
    }
  });

  await loadChoices();
  if (!trackInput.value && tracks.length === 1) trackInput.value = tracks[0].name;
  updateNewTrack();

  return () => {
    stopped = true;
    clearTimeout(pollTimer);
    clearTimeout(previewTimer);
  };
}

/** The readable message of a stored run error (text or structured). */
export function runErrorMessage(error) {
  if (!error) return "unknown error";
  if (typeof error === "string") return error;
  return error.message || JSON.stringify(error);
}

function errorFactsOfRun(error) {
  if (!error || typeof error !== "object") return null;
  const facts = [];
  for (const key of ["column", "row", "unit"]) {
    if (error[key] !== undefined && error[key] !== null) facts.push(`${key[0].toUpperCase()}${key.slice(1)}: ${error[key]}`);
  }
  return facts.length ? h("ul", { class: "error-facts" }, facts.map((f) => h("li", {}, f))) : null;
}
