// Form errors in the form's own words, next to the field, with the bounds the service uses.
// The bounds come from the OpenAPI schema (the service's own validation), never copied here.

import { h } from "./dom.js";
import { ApiError } from "./api.js";

/** {min, max, minExclusive, maxExclusive} of an OpenAPI property (anyOf [number, null] too). */
export function boundsOf(prop) {
  if (!prop) return {};
  const p = Array.isArray(prop.anyOf) ? prop.anyOf.find((x) => x.type === "number" || x.type === "integer") || prop : prop;
  const out = {};
  if (p.minimum !== undefined) out.min = p.minimum;
  if (p.exclusiveMinimum !== undefined) Object.assign(out, { min: p.exclusiveMinimum, minExclusive: true });
  if (p.maximum !== undefined) out.max = p.maximum;
  if (p.exclusiveMaximum !== undefined) Object.assign(out, { max: p.exclusiveMaximum, maxExclusive: true });
  return out;
}

/**
 * Give a number input the schema's bounds; `scale` converts the form's unit to the API's
 * (e.g. 1e6 for kN/mm shown, N/m stored). The input keeps them for checkNumber.
 */
export function applyBounds(input, prop, scale = 1) {
  const b = boundsOf(prop);
  const bounds = {
    min: b.min !== undefined ? b.min / scale : undefined,
    max: b.max !== undefined ? b.max / scale : undefined,
    minExclusive: !!b.minExclusive,
    maxExclusive: !!b.maxExclusive,
  };
  if (bounds.min !== undefined) input.min = String(bounds.minExclusive ? bounds.min : bounds.min);
  if (bounds.max !== undefined) input.max = String(bounds.max);
  input.dataset.bounds = JSON.stringify(bounds);
  return bounds;
}

function num(x) {
  return Number(x.toPrecision(6)).toLocaleString("en", { maximumFractionDigits: 6 });
}

/** What is wrong with a number input's value, in words ("" when nothing; blank allowed
 * unless `required`). */
export function numberProblem(input, { required = false } = {}) {
  const raw = input.value.trim();
  if (raw === "") return input.validity && input.validity.badInput ? "must be a number" : (required ? "is required" : "");
  const v = Number(raw);
  if (!Number.isFinite(v)) return "must be a number";
  const b = input.dataset.bounds ? JSON.parse(input.dataset.bounds) : {};
  const lo = b.min;
  const hi = b.max;
  const tooLow = lo !== undefined && (b.minExclusive ? v <= lo : v < lo);
  const tooHigh = hi !== undefined && (b.maxExclusive ? v >= hi : v > hi);
  if (tooLow || tooHigh) {
    if (lo !== undefined && hi !== undefined) return `must be ${b.minExclusive ? "above" : "at least"} ${num(lo)} and ${b.maxExclusive ? "below" : "at most"} ${num(hi)}`;
    if (lo !== undefined) return `must be ${b.minExclusive ? "greater than" : "at least"} ${num(lo)}`;
    return `must be ${b.maxExclusive ? "less than" : "at most"} ${num(hi)}`;
  }
  return "";
}

function labelOf(control) {
  const label = control.id ? document.querySelector(`label[for="${CSS.escape(control.id)}"]`) : null;
  return label ? label.textContent.trim() : control.name || "This field";
}

/** Show `message` under `control` (its label first), mark it invalid and describe it. */
export function showFieldError(control, message) {
  const wrap = control.closest(".field") || control.parentElement;
  let box = wrap.querySelector(":scope > .field-error");
  if (!box) {
    box = h("p", { class: "field-error", id: `${control.id || control.name}-error` });
    wrap.appendChild(box);
  }
  box.textContent = `${labelOf(control)} ${message}`.replace(/\s+/g, " ");
  control.setAttribute("aria-invalid", "true");
  const described = (control.getAttribute("aria-describedby") || "").split(" ").filter(Boolean);
  if (!described.includes(box.id)) control.setAttribute("aria-describedby", [...described, box.id].join(" "));
}

/** Remove every field error of a form. */
export function clearFieldErrors(form) {
  for (const box of form.querySelectorAll(".field-error")) {
    const control = box.parentElement.querySelector("[aria-describedby]");
    if (control) {
      const rest = control.getAttribute("aria-describedby").split(" ").filter((x) => x && x !== box.id);
      if (rest.length) control.setAttribute("aria-describedby", rest.join(" "));
      else control.removeAttribute("aria-describedby");
    }
    box.remove();
  }
  for (const el of form.querySelectorAll("[aria-invalid]")) el.removeAttribute("aria-invalid");
}

/**
 * Put an API error next to the form controls it names (by form name), in the form's words:
 * the API's field names become the controls' labels. Returns the controls marked.
 */
export function showServerErrors(form, err, rename = {}) {
  if (!(err instanceof ApiError)) return [];
  const marked = [];
  const perField = new Map();
  const detail = err.detail;
  const list = Array.isArray(detail) ? detail : (detail && Array.isArray(detail.errors) ? detail.errors : []);
  for (const e of list) {
    const loc = Array.isArray(e.loc) ? e.loc.filter((p) => !["body", "query", "path", "form"].includes(p)) : [];
    const name = loc.join(".");
    if (name && !perField.has(name)) perField.set(name, String(e.msg || ""));
  }
  for (const name of err.fields || []) if (!perField.has(name)) perField.set(name, err.message);
  for (const [name, text] of perField) {
    const control = form.querySelector(`[name="${CSS.escape(rename[name] || name)}"]`);
    if (!control) continue;
    const label = labelOf(control);
    let words = text.replace(/^Value error, /, "").replace(/^Input should be/, "must be");
    // The API's own names of the fields (this one and any other of the form the message
    // mentions) become the labels the user sees; longest names first (a name inside another).
    const names = new Map(Object.entries(rename));
    for (const c of form.querySelectorAll("[name]")) if (c.name && !names.has(c.name)) names.set(c.name, c.name);
    for (const [api, formName] of [...names].sort((a, b) => b[0].length - a[0].length)) {
      const c = form.querySelector(`[name="${CSS.escape(formName)}"]`);
      if (c && words.includes(api)) words = words.split(api).join(labelOf(c).toLowerCase());
    }
    if (words.toLowerCase().startsWith(label.toLowerCase())) words = words.slice(label.length).trim();
    showFieldError(control, words);
    marked.push(control);
  }
  return marked;
}

/** `text` with the API's names of the form's fields replaced by the labels the user sees
 * ("start_chainage_m is required" -> "Start chainage (m) is required"). */
export function inFormWords(form, text) {
  let out = String(text);
  const controls = [...form.querySelectorAll("[name]")].sort((a, b) => b.name.length - a.name.length);
  for (const c of controls) {
    if (!c.name || !out.includes(c.name)) continue;
    out = out.split(c.name).join(`“${labelOf(c)}”`);
  }
  return out.replace(/Input should be/g, "must be").replace(/^Value error, /, "");
}
