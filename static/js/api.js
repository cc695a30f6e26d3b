// Thin client of the REST API (/api/v1) and the readable form of its errors.

export const API = "/api/v1";

/** An error answered by the API, with the parsed detail kept for display. */
export class ApiError extends Error {
  constructor(status, detail, url) {
    const described = describeDetail(detail);
    super(described.message || `HTTP ${status}`);
    this.status = status;
    this.detail = detail;
    this.url = url;
    this.items = described.items;
    this.fields = described.fields;
  }
}

function locName(loc) {
  if (!Array.isArray(loc)) return "";
  // FastAPI prefixes with "body"/"query"/"path"; the last part is the field name.
  const parts = loc.filter((p) => !["body", "query", "path", "form"].includes(p));
  return parts.join(".");
}

/** The readable message of a stored run error (text or structured). */
export function runErrorMessage(error) {
  if (!error) return "unknown error";
  if (typeof error === "string") return error;
  return error.message || JSON.stringify(error);
}

/**
 * Turn an API error detail into {message, items, fields}: a one-line message, a list of
 * specific facts (column, row, unit, field) to show, and the form fields concerned.
 * Accepts the shapes FastAPI produces: a string, an object ({message, column, row, unit, ...})
 * or a list of validation errors ({loc, msg}).
 */
export function describeDetail(detail) {
  const items = [];
  const fields = [];
  if (detail === null || detail === undefined) return { message: "", items, fields };
  if (typeof detail === "string") return { message: detail, items, fields };
  if (Array.isArray(detail)) {
    for (const err of detail) {
      const name = locName(err.loc);
      if (name) fields.push(name);
      items.push(name ? `${name}: ${err.msg}` : String(err.msg ?? JSON.stringify(err)));
    }
    return { message: "Some fields are not valid.", items, fields };
  }
  if (typeof detail === "object") {
    const message = detail.message || detail.msg || detail.error || detail.detail || "";
    const labels = {
      column: "Column", row: "Row", unit: "Unit", field: "Field", expected: "Expected",
      value: "Value", line: "Line",
    };
    for (const [key, label] of Object.entries(labels)) {
      if (detail[key] !== undefined && detail[key] !== null && detail[key] !== "") {
        items.push(`${label}: ${detail[key]}`);
      }
    }
    if (detail.field) fields.push(String(detail.field));
    // The message already names the first invalid field; list them all only when several.
    if (Array.isArray(detail.errors) && detail.errors.length > 1) {
      const nested = describeDetail(detail.errors);
      items.push(...nested.items);
      fields.push(...nested.fields);
    }
    return { message: typeof message === "string" ? message : JSON.stringify(message), items, fields, column: detail.column };
  }
  return { message: String(detail), items, fields };
}

async function parseBody(response) {
  const type = response.headers.get("content-type") || "";
  if (type.includes("application/json")) {
    try {
      return await response.json();
    } catch {
      return null;
    }
  }
  return await response.text();
}

// The client reads only keys the OpenAPI schema gives (no guessing between shapes). Tests check
// it: with window.__tpKeyLog set to an array before the app loads, every key read from an
// answer is recorded as {method, url, path}, and tests/browser/test_client_keys.py looks each
// one up in the served /openapi.json. Without the flag answers are returned untouched.
const NOT_KEYS = new Set(["then", "toJSON", "constructor"]);

function watched(body, method, url) {
  const log = globalThis.__tpKeyLog;
  if (!Array.isArray(log) || body === null || typeof body !== "object") return body;
  const seen = new Set();
  const proxies = new WeakMap();
  const wrap = (obj, path) => {
    if (proxies.has(obj)) return proxies.get(obj);
    const proxy = new Proxy(obj, {
      get(target, prop, receiver) {
        const value = Reflect.get(target, prop, receiver);
        if (typeof prop !== "string" || NOT_KEYS.has(prop)) return value;
        const index = Array.isArray(target);
        if (index && !/^\d+$/.test(prop)) return value; // length, map, slice, ...
        const next = index ? [...path, "[]"] : [...path, prop];
        if (!index && (Object.hasOwn(target, prop) || value === undefined)) {
          const key = `${method} ${url} ${next.join(".")}`;
          if (!seen.has(key)) {
            seen.add(key);
            log.push({ method, url, path: next });
          }
        }
        return value !== null && typeof value === "object" ? wrap(value, next) : value;
      },
    });
    proxies.set(obj, proxy);
    return proxy;
  };
  return wrap(body, []);
}

let openapi = null;

/** The service's OpenAPI document (fetched once): the vocabulary the pages build forms from. */
export function apiSchema() {
  if (!openapi) {
    openapi = fetch("/openapi.json", { headers: { Accept: "application/json" } }).then((r) => {
      if (!r.ok) throw new ApiError(r.status, r.statusText, "/openapi.json");
      return r.json();
    });
    openapi.catch(() => {
      openapi = null;
    });
  }
  return openapi;
}

/**
 * The runs still to reprocess when the error is the API's 409 `status: "updating"` (a track's
 * runs being reprocessed after a vehicle edit: its derived data is answered once complete),
 * else null.
 */
export function updatingRunsLeft(err) {
  const d = err instanceof ApiError ? err.detail : null;
  if (err.status !== 409 || !d || typeof d !== "object" || d.status !== "updating") return null;
  return Number.isFinite(d.runs_left) ? d.runs_left : 0;
}

const UPDATING_RETRY_MS = 2000;
const UPDATING_MAX_WAIT_MS = 10 * 60 * 1000; // a large fleet's reprocess takes minutes
const waiting = new Map(); // url -> runs left, while a read waits for a reprocess to end

/** The page-wide "updating" notice: shown while any read waits, with the fewest runs left. */
function showUpdating() {
  const box = document.getElementById("updating");
  if (!box) return;
  if (!waiting.size) {
    box.hidden = true;
    box.textContent = "";
    return;
  }
  const left = Math.min(...waiting.values());
  const runs = `${left} run${left === 1 ? "" : "s"}`;
  box.textContent = `Updating — ${runs} left: a vehicle edit is reprocessing this track's runs; the results are shown once the new ones are complete.`;
  box.hidden = false;
}

async function fetchOnce(url, options) {
  let response;
  try {
    response = await fetch(url, { headers: { Accept: "application/json" }, ...options });
  } catch (err) {
    throw new ApiError(0, `The service cannot be reached (${err.message}).`, url);
  }
  const body = await parseBody(response);
  if (!response.ok) {
    const detail = body && typeof body === "object" && "detail" in body ? body.detail : body;
    throw new ApiError(response.status, detail || response.statusText, url);
  }
  return body;
}

/**
 * Fetch JSON from the API; throws ApiError with the server's detail on HTTP errors. A read
 * answered "updating" (409) is not an error to the page: the notice says how many runs are
 * left and the read is tried again until the track is settled, or the page is left.
 */
export async function apiFetch(path, options = {}) {
  const url = path.startsWith("http") || path.startsWith("/") ? path : `${API}/${path}`;
  const method = (options.method || "GET").toUpperCase();
  const page = globalThis.location ? globalThis.location.hash : "";
  const until = Date.now() + UPDATING_MAX_WAIT_MS;
  for (;;) {
    try {
      const body = await fetchOnce(url, options);
      if (waiting.delete(url)) showUpdating();
      return watched(body, method, url);
    } catch (err) {
      const left = method === "GET" ? updatingRunsLeft(err) : null;
      const stay = left !== null && Date.now() < until && (!globalThis.location || globalThis.location.hash === page);
      if (!stay) {
        if (waiting.delete(url)) showUpdating();
        throw err;
      }
      waiting.set(url, left);
      showUpdating();
      await new Promise((resolve) => setTimeout(resolve, UPDATING_RETRY_MS));
    }
  }
}

/**
 * Every item of a paged list (`{data, count}` answers: tracks, vehicles, runs), fetched a page
 * of `pageSize` (the API's largest) at a time by `offset`: the first page says how many there
 * are, the others come together. `path` may carry its own query (`runs?track=3`).
 */
export async function apiFetchAll(path, pageSize = 1000) {
  const sep = path.includes("?") ? "&" : "?";
  const page = (offset) => apiFetch(`${path}${sep}limit=${pageSize}&offset=${offset}`);
  const first = await page(0);
  const total = Number.isFinite(first.count) ? first.count : first.data.length;
  const offsets = [];
  for (let o = first.data.length; o < total && first.data.length > 0; o += pageSize) offsets.push(o);
  const rest = await Promise.all(offsets.map(page));
  return [first, ...rest].flatMap((p) => p.data);
}

/** GET JSON; resolves to null instead of throwing when the endpoint answers 404/405. */
export async function apiGetOptional(path) {
  try {
    return await apiFetch(path);
  } catch (err) {
    if (err instanceof ApiError && (err.status === 404 || err.status === 405)) return null;
    throw err;
  }
}

/** POST a JSON body. */
export function apiPostJson(path, body) {
  return apiFetch(path, {
    method: "POST",
    headers: { "Content-Type": "application/json", Accept: "application/json" },
    body: JSON.stringify(body),
  });
}

/**
 * POST multipart form data with upload progress (fetch has no upload progress events).
 * onProgress(fraction) is called with 0..1 while the body is sent. Resolves with the parsed
 * JSON answer; rejects with ApiError carrying the server's detail.
 */
export function uploadWithProgress(path, formData, onProgress) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", `${API}/${path}`);
    xhr.setRequestHeader("Accept", "application/json");
    xhr.responseType = "text";
    xhr.upload.addEventListener("progress", (ev) => {
      if (ev.lengthComputable && onProgress) onProgress(ev.loaded / ev.total);
    });
    xhr.upload.addEventListener("load", () => onProgress && onProgress(1));
    xhr.addEventListener("load", () => {
      let body = xhr.responseText;
      try {
        body = JSON.parse(xhr.responseText);
      } catch {
        /* not JSON: keep the text */
      }
      if (xhr.status >= 200 && xhr.status < 300) {
        resolve(watched(body, "POST", `${API}/${path}`));
      } else {
        const detail = body && typeof body === "object" && "detail" in body ? body.detail : body;
        reject(new ApiError(xhr.status, detail || xhr.statusText, path));
      }
    });
    xhr.addEventListener("error", () => reject(new ApiError(0, "The upload failed: the service cannot be reached.", path)));
    xhr.addEventListener("abort", () => reject(new ApiError(0, "The upload was cancelled.", path)));
    xhr.send(formData);
  });
}
