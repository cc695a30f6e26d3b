// Separated soft spots that are provisional (the API's `provisional`, `provisional_reason`): a
// vehicle behind them has neither a calibration applied nor its runs' loads declared, and the
// separation reads such a vehicle's error as a stiffness change. One label and one banner,
// shared by the register and the stiffness map.

import { h } from "./dom.js";

const REMEDY = "Calibrate each vehicle named (its page: “Calibrate from its runs”), or declare each run's load (payload or static wheel load) when uploading it; until then treat these zones as candidates to check, not as findings.";
const SHOWN_REASONS = 4; // distinct reasons written out; the others counted

/** The "provisional" label beside a separated soft spot (its reason as the tooltip). */
export function provisionalLabel(item) {
  if (!item || !item.provisional) return null;
  // the space keeps "provisional" a word of its own for copy and speech
  return [" ", h("span", { class: "badge provisional", title: item.provisional_reason || "provisional" }, "provisional")];
}

/**
 * The banner over a list of separated results: how many are provisional, why (each distinct
 * reason: the vehicles and their runs) and what to do; null when none is. `subject(n)` says
 * what the n provisional items are ("3 soft spots are"), `id` is the element's id.
 */
export function provisionalBanner(items, subject, id) {
  const marked = items.filter((x) => x && x.provisional);
  if (!marked.length) return null;
  const reasons = [...new Set(marked.map((x) => x.provisional_reason).filter(Boolean))];
  const shown = reasons.slice(0, SHOWN_REASONS);
  return h("div", { class: "message warning", role: "status", id },
    h("strong", {}, "Provisional: "),
    `${subject(marked.length)} separated with vehicles whose parameters or loads are not known — `,
    shown.join("; "),
    reasons.length > shown.length ? ` and ${reasons.length - shown.length} more` : "",
    `. ${REMEDY}`);
}

/** "1 soft spot is" / "3 soft spots are": the usual subject of the banner. */
export function spotsAre(n) {
  return n === 1 ? "1 soft spot is" : `${n} soft spots are`;
}
