// Client-side look at the head of a run log (first ~64 KB): its bytes (gzip decompressed), and
// its first rows for display and the sample-rate estimate. Which column is which, and in what
// unit, is never guessed here: the service's preview (POST /views/csv-preview, the engine's own
// reader) answers that, so the page and an upload always agree.

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
  const candidates = [",", ";", "\t"]; // the engine's delimiters (whitespace aside)
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

function median(values) {
  const v = values.filter((x) => Number.isFinite(x)).sort((a, b) => a - b);
  if (v.length === 0) return NaN;
  return v[Math.floor(v.length / 2)];
}

function columnValues(parsed, idx) {
  return parsed.numericRows.map((r) => r[idx]);
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
