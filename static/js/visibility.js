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
  const losses = limit.min_loss_pct.filter((v) => v !== null && v !== undefined);
  const digits = lossDigits(losses);
  const parts = limit.zone_length_m.map((len, i) => {
    const loss = limit.min_loss_pct[i];
    return loss === null || loss === undefined
      ? `any loss over ${fmt(len, 0)} m`
      : `losses below ${fmt(loss, digits)} % over ${fmt(len, 0)} m`;
  });
  const list = parts.length > 1 ? `${parts.slice(0, -1).join(", ")} or ${parts[parts.length - 1]}` : parts[0];
  return `This pass could not see ${list} (its detection threshold: dips of ${fmt(limit.threshold_mm, 2)} mm).`;
}

/** Decimals that keep different limits apart: whole percent unless two limits that differ
 * would read alike (16.35 and 15.75 both as "16 %"), then one decimal. */
export function lossDigits(losses) {
  const differ = (a, b) => Math.abs(a - b) >= 0.05;
  for (let i = 0; i < losses.length; i++) {
    for (let j = i + 1; j < losses.length; j++) {
      if (differ(losses[i], losses[j]) && fmt(losses[i], 0) === fmt(losses[j], 0)) return 1;
    }
  }
  return 0;
}
