// Deleting a track from its page: a confirmation in the page (what goes: the track, its runs
// and everything derived from them), then DELETE /api/v1/tracks/{id} and back home.

import { h, announce, plural } from "../../dom.js";
import { apiFetch } from "../../api.js";

/** The "Delete track…" control with its in-page confirmation. */
export function deleteTrackControl(track, nRuns) {
  const msg = h("p", { class: "message error", role: "alert", hidden: true, id: "delete-track-error" });
  const confirmBtn = h("button", { type: "button", class: "button danger", id: "delete-track-confirm" }, "Delete the track and its runs");
  const cancelBtn = h("button", { type: "button", class: "button secondary", id: "delete-track-cancel" }, "Cancel");
  const confirmBox = h("div", { class: "message warning", role: "group", "aria-labelledby": "delete-track-q", hidden: true, id: "delete-track-box" },
    h("p", { id: "delete-track-q" },
      `Delete track “${track.name}” with its ${plural(nRuns, "run")}, their profiles and soft spots, and the track's register, limits and surveys? This cannot be undone.`),
    h("div", { class: "actions" }, confirmBtn, cancelBtn), msg);
  const openBtn = h("button", { type: "button", class: "button small danger", id: "delete-track", "aria-expanded": "false", "aria-controls": "delete-track-box" }, "Delete track…");
  openBtn.addEventListener("click", () => {
    confirmBox.hidden = false;
    openBtn.setAttribute("aria-expanded", "true");
    cancelBtn.focus();
  });
  cancelBtn.addEventListener("click", () => {
    confirmBox.hidden = true;
    openBtn.setAttribute("aria-expanded", "false");
    openBtn.focus();
  });
  confirmBtn.addEventListener("click", async () => {
    confirmBtn.disabled = true;
    try {
      await apiFetch(`tracks/${encodeURIComponent(track.id)}`, { method: "DELETE" });
      announce(`Track ${track.name} deleted.`);
      window.location.hash = "#/";
    } catch (err) {
      msg.textContent = `Not deleted: ${err.message}`;
      msg.hidden = false;
      confirmBtn.disabled = false;
    }
  });
  return h("div", { class: "delete-track" }, openBtn, confirmBox);
}
