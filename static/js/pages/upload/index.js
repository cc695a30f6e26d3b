// Upload page: choose or drop a log, check the preview and the column/unit mapping, say where
// the run was recorded, upload with progress, then follow processing until the run is ready.
// state.js holds the vocabulary and page state, view.js the DOM, actions.js the behaviour.

import { h } from "../../dom.js";
import { apiSchema } from "../../api.js";
import { createState, vocabularyOf } from "./state.js";
import { buildForm, updateNewTrack } from "./view.js";
import { bind, loadChoices, loadUsualVehicle } from "./actions.js";
import { bindGnss } from "./gnss.js";

export async function render(main) {
  main.appendChild(h("h1", {}, "Upload a run"));
  let state;
  try {
    state = createState(vocabularyOf(await apiSchema()));
  } catch (err) {
    main.appendChild(h("p", { class: "message error", role: "alert" }, `Cannot load the upload form: ${err.message}`));
    return null;
  }
  const ui = buildForm(main, state);
  bind(ui, state);
  bindGnss(ui, state); // start chainage optional for GNSS logs on tracks with a centerline
  await loadChoices(ui, state);
  if (!ui.trackInput.value && state.tracks.length === 1) ui.trackInput.value = state.tracks[0].name;
  updateNewTrack(ui, state);
  if (ui.trackInput.value) await loadUsualVehicle(ui, state);

  return () => {
    state.stopped = true;
    clearTimeout(state.pollTimer);
    clearTimeout(state.previewTimer);
  };
}
