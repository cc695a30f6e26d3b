// What one pass could see: its detection limit in words (GET /runs/{id} -> detection_limit).

import { fmt } from "./dom.js";

/**
 * What a pass could not have seen, in words, from its detection limit
 * ({zone_length_m: [...], min_loss_pct: [... or null], threshold_mm}).
 */
export function unseenText(limit) {
  if (!limit || !Array.isArray(limit.zone_length_m) || limit.zone_length_m.length === 0) {
    return "What this pass could detect is not known (processed before detection limits were reported; reprocess it to see).";
  }
  const parts = limit.zone_length_m.map((len, i) => {
    const loss = limit.min_loss_pct[i];
    return loss === null || loss === undefined
      ? `any loss over ${fmt(len, 0)} m`
      : `losses below ${fmt(loss, 0)} % over ${fmt(len, 0)} m`;
  });
  const list = parts.length > 1 ? `${parts.slice(0, -1).join(", ")} or ${parts[parts.length - 1]}` : parts[0];
  return `This pass could not see ${list} (its detection threshold: dips of ${fmt(limit.threshold_mm, 2)} mm).`;
}
