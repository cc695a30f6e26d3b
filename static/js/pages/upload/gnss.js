// Positions from GNSS on the upload form (issue 11): when the log's preview shows latitude and
// longitude columns and the chosen track has a centerline, the start chainage is optional (the
// service places the run by its fixes); otherwise it stays as it was.

import { h } from "../../dom.js";
import { apiGetOptional } from "../../api.js";
import { canPlaceWithoutStart, effectiveReading } from "./state.js";
import { showStartRequired } from "./view.js";

export function bindGnss(ui, state) {
  const form = ui.startInput.form || document.body;
  const note = h("p", { class: "hint", id: "gnss-note", role: "status", hidden: true });
  ui.startInput.insertAdjacentElement("afterend", note);
  const known = new Map(); // track name -> Promise<boolean> (has a centerline)
  let touched = false;
  let timer = null;

  const hasCenterline = (track) => {
    if (!known.has(track)) {
      const url = `/api/v1/tracks/${encodeURIComponent(track)}/centerline/summary`;
      known.set(track, apiGetOptional(url).then(Boolean).catch(() => false));
    }
    return known.get(track);
  };

  const say = (text) => {
    if (note.textContent !== text) note.textContent = text; // no mutation, no loop
    note.hidden = text === "";
  };

  async function update() {
    const reading = effectiveReading(state);
    const fixes = Boolean(reading.mapping.lat && reading.mapping.lon);
    const track = ui.trackInput.value.trim();
    const placed = fixes && track !== "" && (await hasCenterline(track));
    state.gnssPlaced = placed; // canPlaceWithoutStart: the start chainage becomes optional
    showStartRequired(ui, canPlaceWithoutStart(state));
    if (placed) {
      if (!touched && ui.startInput.value === "0") ui.startInput.value = "";
      ui.startInput.placeholder = "from the GNSS fixes";
      say(`Optional: the log has GNSS fixes (${reading.mapping.lat.column}, ${reading.mapping.lon.column}) and track “${track}” has a centerline, so the run is placed by its fixes when this is left empty.`);
    } else {
      ui.startInput.placeholder = "e.g. 1234.5";
      say(fixes ? "The log has GNSS fixes; give the track a centerline (on its track page) to place runs by them." : "");
    }
  }
  const soon = () => {
    clearTimeout(timer);
    timer = setTimeout(update, 150);
  };
  ui.startInput.addEventListener("input", () => { touched = true; });
  ui.trackInput.addEventListener("input", soon);
  ui.trackInput.addEventListener("change", soon);
  // The preview (and so the mapping) arrives asynchronously: follow the form's changes.
  new MutationObserver(soon).observe(form, { childList: true, subtree: true });
}
