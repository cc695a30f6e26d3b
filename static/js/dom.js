// Small DOM helpers. Every piece of text goes through text nodes / textContent so that
// user-supplied names (tracks, vehicles, files) can never be interpreted as HTML.

const PROPS = new Set(["value", "checked", "disabled", "hidden", "selected", "multiple", "open"]);

/**
 * Create an element: h("a", {href: "#/", class: "x", onclick: fn}, "text", childNode, [more]).
 * Attribute values are set with setAttribute (never parsed as HTML); children that are strings
 * or numbers become text nodes; null/undefined/false children are skipped.
 */
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [key, val] of Object.entries(attrs || {})) {
    if (val === null || val === undefined || val === false) continue;
    if (key.startsWith("on") && typeof val === "function") {
      el.addEventListener(key.slice(2).toLowerCase(), val);
    } else if (PROPS.has(key)) {
      el[key] = val;
    } else if (key === "dataset") {
      Object.assign(el.dataset, val);
    } else {
      el.setAttribute(key, val === true ? "" : String(val));
    }
  }
  append(el, children);
  return el;
}

/** Append children (strings, numbers, nodes, nested arrays) to an element. */
export function append(el, children) {
  for (const child of children.flat(Infinity)) {
    if (child === null || child === undefined || child === false) continue;
    el.appendChild(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

/** Remove every child of an element. */
export function clear(el) {
  while (el.firstChild) el.removeChild(el.firstChild);
  return el;
}

let announceTimer = null;

/** Tell screen-reader users about a status change (aria-live region). */
export function announce(message) {
  const region = document.getElementById("announcer");
  if (!region) return;
  region.textContent = "";
  clearTimeout(announceTimer);
  // A short delay makes repeated identical messages be read again.
  announceTimer = setTimeout(() => {
    region.textContent = message;
  }, 50);
}

/** Format a number with a fixed number of decimals, "—" for missing values. */
export function fmt(value, digits = 2) {
  if (value === null || value === undefined || Number.isNaN(Number(value))) return "—";
  return Number(value).toFixed(digits);
}

/**
 * A chainage as railways write it, km+m: 12645.04 -> "12+645.0" (the API answers in metres).
 * The Python twin is app/services/notation.py km_m.
 */
export function fmtKm(value, digits = 1) {
  if (value === null || value === undefined || !Number.isFinite(Number(value))) return "—";
  const v = Number(value);
  const scaled = Number(Math.abs(v).toFixed(digits));
  const km = Math.floor(scaled / 1000);
  const m = (scaled - 1000 * km).toFixed(digits).padStart(digits > 0 ? 4 + digits : 3, "0");
  return `${v < 0 ? "-" : ""}${km}+${m}`;
}

/** A stretch from one chainage to another, km+m: "0+120.0–0+126.0". */
export function fmtKmRange(a, b, digits = 1) {
  return `${fmtKm(a, digits)}–${fmtKm(b, digits)}`;
}

/** An engine or API message as a sentence: capital first letter, closing full stop. */
export function sentence(text) {
  const t = String(text || "").trim();
  if (!t) return "";
  const first = t.charAt(0).toUpperCase() + t.slice(1);
  return /[.!?]$/.test(first) ? first : `${first}.`;
}

/** A count with its noun: "1 run", "2 runs", "1 soft spot" ("1,200 runs" for large n). */
export function plural(n, word, words = `${word}s`) {
  return `${Number(n).toLocaleString("en")} ${n === 1 ? word : words}`;
}

/** Format an ISO date/time for display in the user's locale ("—" when missing). */
export function fmtDate(value) {
  if (!value) return "—";
  const d = new Date(value);
  if (Number.isNaN(d.getTime())) return String(value);
  return d.toLocaleString(undefined, {
    year: "numeric", month: "short", day: "2-digit", hour: "2-digit", minute: "2-digit",
  });
}

/** A date as YYYY-MM-DD in the user's time zone ("—" when missing). */
export function fmtDay(value) {
  if (!value) return "—";
  const d = new Date(value);
  if (Number.isNaN(d.getTime())) return String(value);
  const pad = (n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}`;
}

/** A labelled form control: returns {wrap, input} with the label tied to the control. */
export function field(labelText, control, hint) {
  const id = control.id || `f-${Math.random().toString(36).slice(2, 9)}`;
  control.id = id;
  const parts = [h("label", { for: id }, labelText), control];
  if (hint) {
    const hintId = `${id}-hint`;
    control.setAttribute("aria-describedby", hintId);
    parts.push(h("small", { id: hintId, class: "hint" }, hint));
  }
  return h("div", { class: "field" }, parts);
}

/**
 * A table in a box that scrolls sideways on a narrow screen: a labelled region in the tab
 * order, so that keyboard users can scroll it too (axe: scrollable-region-focusable).
 */
export function scrollTable(label, table, extraClass = "") {
  return h("div", { class: `table-scroll${extraClass ? ` ${extraClass}` : ""}`, tabindex: "0", role: "region", "aria-label": label }, table);
}

/** Offer a Blob to the user as a file download. */
export function downloadBlob(blob, filename) {
  const url = URL.createObjectURL(blob);
  const a = h("a", { href: url, download: filename, hidden: true });
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

/** A status message box (role=status or alert) whose text can be replaced. */
export function messageBox(kind = "info") {
  const el = h("div", { class: `message ${kind}`, role: kind === "error" ? "alert" : "status", hidden: true });
  return {
    el,
    show(text, newKind = kind, extra = []) {
      el.className = `message ${newKind}`;
      el.setAttribute("role", newKind === "error" ? "alert" : "status");
      clear(el);
      append(el, [text, extra]);
      el.hidden = false;
    },
    hide() {
      el.hidden = true;
      clear(el);
    },
  };
}
