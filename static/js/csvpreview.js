// Client-side look at the head of a run log (first ~64 KB): delimiter, header, first rows and a
// first guess of which column is which and in what unit. The server's preview (engine.logio),
// when available, has the last word; this keeps the page useful without it.

export const HEAD_BYTES = 64 * 1024;

/** Read the first bytes of a File as text, decompressing gzip (.gz) on the fly. */
export async function readHead(file, maxBytes = HEAD_BYTES) {
  const magic = new Uint8Array(await file.slice(0, 2).arrayBuffer());
  const gzip = magic[0] === 0x1f && magic[1] === 0x8b;
  if (!gzip) {
    const buf = await file.slice(0, maxBytes).arrayBuffer();
    return { text: new TextDecoder("utf-8").decode(buf), gzip: false, complete: file.size <= maxBytes };
  }
  if (typeof DecompressionStream === "undefined") {
    return { text: "", gzip: true, complete: false, unsupported: true };
  }
  const decoder = new TextDecoder("utf-8");
  const stream = file.stream().pipeThrough(new DecompressionStream("gzip"));
  const reader = stream.getReader();
  let text = "";
  let complete = false;
  try {
    while (text.length < maxBytes) {
      const { value, done } = await reader.read();
      if (done) {
        complete = true;
        break;
      }
      text += decoder.decode(value, { stream: true });
    }
  } finally {
    reader.cancel().catch(() => {});
  }
  return { text, gzip: true, complete };
}

function detectDelimiter(line) {
  const candidates = [",", ";", "\t", "|"];
  let best = ",";
  let bestCount = 0;
  for (const c of candidates) {
    const n = line.split(c).length - 1;
    if (n > bestCount) {
      best = c;
      bestCount = n;
    }
  }
  return best;
}

function splitLine(line, delimiter) {
  return line.split(delimiter).map((cell) => cell.trim().replace(/^"(.*)"$/, "$1"));
}

/**
 * Parse the head of a CSV: {delimiter, columns, rows (strings), numericRows, skipped, totalLines}.
 * The last line is dropped when the head is cut mid-file (it may be partial).
 */
export function parseHead(text, complete = true) {
  let body = text.replace(/^\uFEFF/, "");
  const lines = body.split(/\r\n|\n|\r/);
  if (!complete) lines.pop();
  const content = [];
  let skipped = 0;
  for (const line of lines) {
    if (line.trim() === "" || line.trimStart().startsWith("#")) {
      skipped += 1;
      continue;
    }
    content.push(line);
  }
  if (content.length === 0) return { delimiter: ",", columns: [], rows: [], numericRows: [], skipped };
  const delimiter = detectDelimiter(content[0]);
  const columns = splitLine(content[0], delimiter);
  const rows = content.slice(1).map((l) => splitLine(l, delimiter));
  const numericRows = rows.map((r) => r.map((c) => (c === "" ? NaN : Number(c))));
  body = null;
  return { delimiter, columns, rows, numericRows, skipped };
}

const ROLE_PATTERNS = {
  time: [/^time/i, /^t$/i, /^t_/i, /timestamp/i, /epoch/i, /^ts$/i, /^sec/i],
  accel: [/^acc/i, /^a_?z/i, /accel/i, /^az/i, /vert.*acc/i],
  pitch_rate: [/pitch/i, /^gyro/i, /^g_?y/i, /^gy/i, /omega/i, /rate/i, /^wy/i],
  speed: [/speed/i, /^vel/i, /^v$/i, /^v_/i, /kmh/i],
  chainage: [/chain/i, /^odo/i, /^dist/i, /^pos/i, /^x_?m$/i, /^km/i],
};

function median(values) {
  const v = values.filter((x) => Number.isFinite(x)).sort((a, b) => a - b);
  if (v.length === 0) return NaN;
  return v[Math.floor(v.length / 2)];
}

function columnValues(parsed, idx) {
  return parsed.numericRows.map((r) => r[idx]);
}

/** Guess the unit of a column from its name and values (null when unsure). */
function guessUnit(role, name, values) {
  const n = name.toLowerCase();
  const med = Math.abs(median(values));
  if (role === "time") {
    if (/epoch|unix/.test(n) || med > 1e8) return "epoch_s";
    if (/(_|\b|\[|\()ms\b|millis/.test(n)) return "ms";
    if (/(_|\b|\[|\()s\b|sec/.test(n)) return "s";
    return null;
  }
  if (role === "accel") {
    if (/mps2|m\/s2|m\/s\^2|ms2|m_s2/.test(n)) return "m/s2";
    if (/(_|\b|\[|\()g\b|_g$/.test(n)) return "g";
    if (Number.isFinite(med) && Math.abs(med - 1) < 0.2) return "g";
    return null;
  }
  if (role === "pitch_rate") {
    if (/dps|deg/.test(n)) return "deg/s";
    if (/radps|rad/.test(n)) return "rad/s";
    return null;
  }
  if (role === "speed") {
    if (/kmh|km\/h|kph/.test(n)) return "km/h";
    if (/mps|m\/s|ms\b/.test(n)) return "m/s";
    return null;
  }
  return null;
}

/**
 * Guess the role of each column: {time, accel, pitch_rate, speed, chainage} → {column, unit}.
 * Also guesses whether gravity is included (accelerations around +1 g / +9.81 m/s²).
 */
export function recognise(parsed) {
  const used = new Set();
  const mapping = {};
  for (const [role, patterns] of Object.entries(ROLE_PATTERNS)) {
    let found = -1;
    for (const pattern of patterns) {
      found = parsed.columns.findIndex((c, i) => !used.has(i) && pattern.test(c));
      if (found >= 0) break;
    }
    if (found >= 0) {
      used.add(found);
      const name = parsed.columns[found];
      mapping[role] = { column: name, unit: guessUnit(role, name, columnValues(parsed, found)) };
    }
  }
  let gravity = null;
  if (mapping.accel) {
    const idx = parsed.columns.indexOf(mapping.accel.column);
    const med = median(columnValues(parsed, idx));
    if (Number.isFinite(med)) {
      const g = mapping.accel.unit === "g" ? 1 : 9.80665;
      gravity = Math.abs(med - g) < 0.2 * g ? "included" : Math.abs(med) < 0.2 * g ? "removed" : null;
    }
  }
  return { mapping, gravity };
}

/** Sample rate (Hz) estimated from the time column of the preview, or null. */
export function estimateRate(parsed, timeColumn, timeUnit) {
  const idx = parsed.columns.indexOf(timeColumn);
  if (idx < 0) return null;
  const t = columnValues(parsed, idx).filter(Number.isFinite);
  if (t.length < 3) return null;
  const steps = [];
  for (let i = 1; i < t.length; i += 1) steps.push(t[i] - t[i - 1]);
  let dt = median(steps);
  if (timeUnit === "ms") dt /= 1000;
  if (!(dt > 0)) return null;
  return 1 / dt;
}
