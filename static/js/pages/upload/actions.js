// Upload page actions: load the choices, read and preview a chosen file (the service's reader
// has the last word), create a vehicle, create the track, upload with progress and follow the
// processing until the run is ready.

import { h, announce } from "../../dom.js";
import { ApiError, apiFetch, apiFetchAll, apiPostJson, runErrorMessage, uploadWithProgress } from "../../api.js";
import { readHead, parseHead } from "../../csvpreview.js";
import {
  clearFieldErrors, inFormWords, numberProblem, showFieldError, showServerErrors,
} from "../../formerrors.js";
import {
  canPlaceWithoutStart, fileRecordedAt, formatBytes, localInputValue,
} from "./state.js";
import {
  DEFAULT_VEHICLE, errorFactsOfRun, errorList, errorText, highlightFields, markFailed, pickVehicle, previewProblems,
  resetProgress, showChoices, showPlacement, showPreview, showPreviewMessage, updateNewTrack,
} from "./view.js";

/** The preview and what follows from it (start chainage required, recording time). */
function showReading(ui, state) {
  if (state.preview) showPreview(ui, state);
  const iso = fileRecordedAt(state);
  const recordedAt = iso ? { local: localInputValue(iso), text: new Date(iso).toLocaleString() } : null;
  showPlacement(ui, state, { recordedAt, canPlace: state.preview ? canPlaceWithoutStart(state) : false });
}

export async function loadChoices(ui, state) {
  try {
    state.tracks = await apiFetchAll("tracks");
  } catch (err) {
    ui.status.show(`Could not load the tracks: ${err.message}`, "error");
  }
  try {
    state.vehicles = await apiFetchAll("vehicles");
  } catch (err) {
    ui.status.show(`Could not load the vehicles: ${err.message}`, "error");
  }
  try {
    // the engine's presets are vehicle names too (stored on first use): offered beside the
    // stored vehicles, so a preset such as "heavy" needs no API call first
    state.presets = Object.keys(await apiFetch("/api/v1/vehicles/presets"));
  } catch {
    state.presets = [DEFAULT_VEHICLE];
  }
  showChoices(ui, state);
}

/** The vehicle of most of a track's runs (its newest 100), kept per track name. */
export async function loadUsualVehicle(ui, state) {
  const name = ui.trackInput.value.trim();
  state.usualVehicle = state.usualVehicle || {};
  const track = state.tracks.find((t) => t.name === name);
  if (track && !(name in state.usualVehicle)) {
    try {
      const runs = await apiFetch(`/api/v1/runs?track=${encodeURIComponent(track.id)}&limit=100`);
      const counts = {};
      for (const r of runs.data) counts[r.vehicle] = (counts[r.vehicle] || 0) + 1;
      const ranked = Object.entries(counts).sort((a, b) => b[1] - a[1]);
      // a tie is no usual vehicle: the form asks rather than guess
      const tie = ranked.length > 1 && ranked[0][1] === ranked[1][1];
      state.usualVehicle[name] = ranked.length && !tie ? ranked[0][0] : null;
      if (tie) (state.mixedVehicles = state.mixedVehicles || {})[name] = ranked.map(([v]) => v);
    } catch {
      state.usualVehicle[name] = null; // the form asks instead
    }
  }
  if (ui.trackInput.value.trim() === name) pickVehicle(ui, state);
}

async function createVehicle(ui, state) {
  const { vehicleName, vehicleInputs, vehicleMsg } = ui;
  const name = vehicleName.value.trim();
  if (!name) {
    vehicleMsg.show("Give the vehicle a name.", "error");
    vehicleName.focus();
    return;
  }
  const params = {};
  clearFieldErrors(ui.vehicleDetails);
  for (const [key, input] of Object.entries(vehicleInputs)) {
    const problem = numberProblem(input, { required: true });
    if (problem) {
      showFieldError(input, problem);
      vehicleMsg.show("Check the marked vehicle parameter.", "error");
      input.focus();
      return;
    }
    params[key] = Number(input.value);
  }
  try {
    await apiPostJson("vehicles", { name, params });
    await loadChoices(ui, state);
    state.vehicleChosen = name;
    pickVehicle(ui, state);
    vehicleMsg.show(`Vehicle ${name} created and selected.`, "success");
  } catch (err) {
    vehicleMsg.show(errorText(err), "error", errorList(err));
    showServerErrors(ui.vehicleDetails, err, Object.fromEntries(Object.keys(vehicleInputs).map((k) => [`params.${k}`, k])));
  }
}

/** The column/unit options the user set explicitly (blank = automatic). */
export function chosenOptions(ui, state) {
  const out = {};
  for (const role of state.roles) {
    const { colSel, unitSel } = ui.selects[role.key];
    if (colSel.value) out[role.column] = colSel.value;
    if (unitSel && unitSel.value) out[role.unit] = unitSel.value;
  }
  if (ui.gravitySel.value) out.gravity = ui.gravitySel.value;
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

async function chooseFile(ui, state, f) {
  state.file = f;
  ui.status.hide();
  ui.fileInfo.textContent = `${f.name} — ${formatBytes(f.size)}`;
  showPreviewMessage(ui, "Reading the first rows…");
  try {
    const head = await readHead(f);
    if (head.unsupported) {
      showPreviewMessage(ui, "This browser cannot preview gzip files; the server will still read it.", "hint");
      return;
    }
    const parsed = parseHead(head.text, head.complete);
    state.preview = { parsed, head, serverAuto: null, serverNow: null };
    showReading(ui, state);
    // The engine's own reading of the head has the last word when the service answers.
    const server = await serverPreview(head.text, {});
    if (server && !state.stopped && state.file === f) {
      state.preview.serverAuto = server;
      state.preview.serverNow = server;
      showReading(ui, state);
      if (Object.keys(chosenOptions(ui, state)).length) refreshServerPreview(ui, state);
    }
  } catch (err) {
    showPreviewMessage(ui, `Cannot preview this file: ${err.message}`, "error");
  }
}

function refreshServerPreview(ui, state) {
  if (!state.preview || !state.preview.serverAuto) return;
  clearTimeout(state.previewTimer);
  state.previewTimer = setTimeout(async () => {
    const f = state.file;
    const server = await serverPreview(state.preview.head.text, chosenOptions(ui, state));
    if (server && !state.stopped && state.file === f) {
      state.preview.serverNow = server;
      showReading(ui, state);
    }
  }, 250);
}

// What the worker is doing (the run's `stage`), as the progress label says it.
const STAGE_TEXT = { queued: "Waiting to be processed", inverting: "Processing", storing: "Storing the result" };

function poll(ui, state, id, started) {
  return new Promise((resolve, reject) => {
    const tick = async () => {
      if (state.stopped) return;
      try {
        const run = await apiFetch(`runs/${encodeURIComponent(id)}`);
        const elapsed = (Date.now() - started) / 1000;
        if (typeof run.progress === "number") ui.processBar.value = Math.max(0, Math.min(1, run.progress));
        const stage = STAGE_TEXT[run.stage] || "Processing";
        ui.processLabel.textContent = `${stage} (${elapsed.toFixed(0)} s)`;
        if (run.status === "done") return resolve(run);
        if (run.status === "failed") return reject(Object.assign(new Error(runErrorMessage(run.error)), { run }));
        state.pollTimer = setTimeout(tick, 600);
      } catch (err) {
        reject(err);
      }
    };
    tick();
  });
}

/** The upload's form data, or null after showing, next to each field, what is wrong. */
function formData(ui, state) {
  const { status, fileInput, trackInput, startInput } = ui;
  clearFieldErrors(ui.form);
  const bad = [];
  const problem = (control, text) => {
    showFieldError(control, text);
    bad.push(control);
  };
  if (!state.file) problem(fileInput, "is missing: choose or drop a run log file");
  const track = trackInput.value.trim();
  if (!track) problem(trackInput, "is required: name the track the run was recorded on");
  const newTrack = track && !state.tracks.some((t) => t.name === track);
  if (!ui.vehicleSel.value) problem(ui.vehicleSel, "is required: choose the vehicle that recorded this log");
  const startProblem = numberProblem(startInput, { required: !canPlaceWithoutStart(state) });
  if (startProblem) {
    problem(startInput, startProblem === "is required"
      ? "is required: the chainage where the log starts (this file has no chainage column)"
      : startProblem);
  }
  const numbers = [ui.payloadInput, ui.wheelLoadInput];
  if (newTrack) numbers.push(ui.trackK, ui.trackSpacing);
  for (const input of numbers) {
    const p = numberProblem(input);
    if (p) problem(input, p);
  }
  if (ui.payloadInput.value.trim() !== "" && ui.wheelLoadInput.value.trim() !== "") {
    problem(ui.wheelLoadInput, "and the payload cannot both be given: give one of them");
  }
  const problems = previewProblems(state);
  if (!bad.length && problems.length && !ui.ignoreProblems.checked) {
    status.show(`The preview found ${problems.length === 1 ? "a problem" : `${problems.length} problems`} in this file (listed under the preview). Fix the column choices, or tick “Upload anyway”.`, "error");
    ui.ignoreProblems.focus();
    return null;
  }
  if (bad.length) {
    status.show(bad.length === 1 ? "Check the marked field." : `Check the ${bad.length} marked fields.`, "error");
    bad[0].focus();
    return null;
  }
  const fd = new FormData();
  fd.append("file", state.file, state.file.name);
  fd.append("track", track);
  if (newTrack) {
    // The new track's details travel with the run: created together or not at all.
    if (ui.trackDesc.value.trim()) fd.append("track_description", ui.trackDesc.value.trim());
    if (ui.trackRail.value.trim()) fd.append("track_rail", ui.trackRail.value.trim());
    if (ui.trackK.value.trim() !== "") fd.append("track_k_nominal", String(Number(ui.trackK.value) * 1e6)); // kN/mm -> N/m
    if (ui.trackSpacing.value.trim() !== "") fd.append("track_spacing", ui.trackSpacing.value.trim());
  }
  if (ui.vehicleSel.value) fd.append("vehicle", ui.vehicleSel.value);
  if (startInput.value !== "") fd.append("start_chainage_m", startInput.value);
  fd.append("direction", ui.directionSel.value);
  if (ui.recordedInput.value) fd.append("recorded_at", new Date(ui.recordedInput.value).toISOString());
  if (ui.payloadInput.value !== "") fd.append("payload_kg", ui.payloadInput.value);
  if (ui.wheelLoadInput.value !== "") fd.append("static_wheel_load_n", ui.wheelLoadInput.value);
  for (const [k, v] of Object.entries(chosenOptions(ui, state))) fd.append(k, v);
  return { fd, track };
}

async function submit(ui, state) {
  const { status, submitBtn, progressBox, uploadBar, processBar, uploadLabel, processLabel } = ui;
  status.hide();
  const data = formData(ui, state);
  if (!data) return;
  resetProgress(ui);
  submitBtn.disabled = true;
  progressBox.hidden = false;
  uploadBar.value = 0;
  processBar.removeAttribute("value");
  uploadLabel.textContent = "Upload 0 %";
  processLabel.textContent = "Processing (waiting)";
  status.show("Uploading…", "info");
  try {
    const created = await uploadWithProgress("runs", data.fd, (frac) => {
      uploadBar.value = frac;
      uploadLabel.textContent = `Upload ${Math.round(frac * 100)} %`;
    });
    uploadBar.value = 1;
    uploadLabel.textContent = "Upload 100 %";
    const id = created.id;
    if (created.duplicate) {
      // A log is one pass: the stored run answers. Say so, and what was not applied.
      processBar.value = 1;
      processLabel.textContent = "Already stored";
      const open = h("a", { href: `#/runs/${encodeURIComponent(id)}`, id: "open-run" }, `Open run ${id}`);
      status.show(created.note || `This log is already stored as run ${id}: a log is one pass, so nothing new was stored. `, created.note ? "warning" : "info", [" ", open]);
      announce(`This log is already stored as run ${id}.`);
      return;
    }
    status.show(`Uploaded as run ${id}. Processing…`, "info");
    announce("Upload complete, processing the run.");
    const run = created.status === "done" ? created : await poll(ui, state, id, Date.now());
    processBar.value = 1;
    processLabel.textContent = "Processing done";
    const link = h("a", { href: `#/runs/${encodeURIComponent(id)}`, id: "open-run" }, "Open the run");
    status.show(`Run ${id} processed. `, "success", [link]);
    announce(`Run ${id} processed.`);
    // Take the user straight to the result; the link stays for the back button.
    setTimeout(() => {
      if (!state.stopped) window.location.hash = `#/runs/${encodeURIComponent(run.id)}`;
    }, 400);
  } catch (err) {
    const failedRun = err.run;
    markFailed(ui, failedRun ? "processing" : "upload");
    if (failedRun) {
      const link = h("a", { href: `#/runs/${encodeURIComponent(failedRun.id)}` }, "See the run");
      status.show(`Processing failed: ${err.message} `, "error", [errorFactsOfRun(failedRun.error), link]);
    } else {
      highlightFields(ui, state, err);
      const marked = showServerErrors(ui.form, err);
      // The summary in the form's words too; the details stay next to the fields.
      status.show(`Not uploaded: ${inFormWords(ui.form, errorText(err))}`, "error", errorList(err, (t) => inFormWords(ui.form, t)));
      if (marked.length) marked[0].focus();
    }
    announce("The upload failed.");
  } finally {
    submitBtn.disabled = false;
  }
}

/** Wire the form's events to the actions above. */
export function bind(ui, state) {
  const { dropZone, fileInput, form } = ui;
  showReading(ui, state);
  ui.trackInput.addEventListener("input", () => {
    updateNewTrack(ui, state);
    clearTimeout(state.usualTimer);
    state.usualTimer = setTimeout(() => loadUsualVehicle(ui, state), 250);
  });
  ui.vehicleSel.addEventListener("change", () => {
    state.vehicleChosen = ui.vehicleSel.value || null;
    pickVehicle(ui, state);
  });
  ui.createVehicleBtn.addEventListener("click", () => createVehicle(ui, state));
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
    if (dropped) chooseFile(ui, state, dropped);
  });
  fileInput.addEventListener("change", () => {
    if (fileInput.files && fileInput.files[0]) chooseFile(ui, state, fileInput.files[0]);
  });
  for (const { colSel, unitSel } of Object.values(ui.selects)) {
    colSel.addEventListener("change", () => refreshServerPreview(ui, state));
    if (unitSel) unitSel.addEventListener("change", () => refreshServerPreview(ui, state));
  }
  ui.gravitySel.addEventListener("change", () => refreshServerPreview(ui, state));
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    submit(ui, state);
  });
}
