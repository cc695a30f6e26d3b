// Plotly helpers shared by the pages: colours, layouts, soft-spot shading and labels.

import { h } from "./dom.js";

// Okabe–Ito palette: distinguishable with the common forms of colour blindness.
export const COLORS = {
  fused: "#0072B2", // blue
  front: "#009E73", // bluish green
  rear: "#CC79A7", // reddish purple
  truth: "#000000",
  accel: "#0072B2",
  pitch: "#D55E00", // vermillion
  speed: "#56B4E9",
  spotFill: "rgba(230, 159, 0, 0.22)", // orange
  spotLine: "#B26F00",
  truthFill: "rgba(86, 180, 233, 0.20)", // sky blue
  truthLine: "#0072B2",
};

/** Where plotly.js is: the page names its versioned (cacheable) URL. */
function plotlySrc() {
  const meta = document.querySelector('meta[name="plotly-src"]');
  return (meta && meta.content) || "/static/vendor/plotly.min.js";
}

let plotlyPromise = null;

/**
 * Load plotly.js (the partial bundle: 1.5 MB, 0.5 MB compressed; the full one, 4.8 MB, when the
 * partial one is not installed: app/web.py) once, when a page first needs a chart: pages
 * without charts never load it, and the others show their content while it arrives.
 * Resolves to window.Plotly.
 */
export function loadPlotly() {
  if (window.Plotly) return Promise.resolve(window.Plotly);
  if (!plotlyPromise) {
    // While it loads, empty chart areas say so (style.css: .plotly-loading .plot:empty).
    document.documentElement.classList.add("plotly-loading");
    plotlyPromise = new Promise((resolve, reject) => {
      const script = document.createElement("script");
      script.src = plotlySrc();
      script.async = true;
      script.onload = () => (window.Plotly ? resolve(window.Plotly) : reject(new Error("plotly.js loaded but defined nothing")));
      script.onerror = () => {
        plotlyPromise = null;
        script.remove();
        reject(new Error(`plotly.js did not load from ${script.src}`));
      };
      document.head.appendChild(script);
    });
    const done = () => document.documentElement.classList.remove("plotly-loading");
    plotlyPromise.then(done, done);
  }
  return plotlyPromise;
}

/** Plotly, once loaded (loadPlotly), or an explanation of why it is not there. */
export function plotly() {
  if (!window.Plotly) throw new Error("plotly.js is not loaded yet (await loadPlotly() first)");
  return window.Plotly;
}

// Track data never leaves the deployment: no share/cloud/edit link or button on any chart.
// plotly.js 4 shows a "Share chart..." button by default (showSendToCloud: true) that uploads
// the chart's data to plotlyServerURL (default: Plotly's cloud); older versions had
// "Edit in Chart Studio" and a link (showLink). All off, the server URL emptied, the buttons
// removed by every name they have had.
export const CONFIG = {
  responsive: true,
  displaylogo: false,
  scrollZoom: false,
  showLink: false,
  linkText: "",
  showSendToCloud: false,
  showEditInChartStudio: false,
  plotlyServerURL: "",
  sendData: false,
  modeBarButtonsToRemove: ["lasso2d", "select2d", "sendChartToCloud", "sendDataToCloud", "editInChartStudio"],
  toImageButtonOptions: { format: "png", scale: 2 },
};

// The terms of the charts and tables, explained where they appear (tooltips, help text).
export const TERMS = {
  loadedProfile: "Loaded profile: the rail level under the passing wheels (mm, positive up), recovered from the body's acceleration and pitch rate. Where the support is soft, the rail dips under load.",
  baseline: "Baseline: the slowly varying level around each point (a moving median over tens of metres). Depths are measured from it, not from 0 mm, so a long gentle slope is not a defect.",
  depth: "Depth: how far the profile dips below its baseline at the soft spot's deepest point, mm (not the level itself: a dip to −0.27 mm on a baseline at +0.04 mm is 0.31 mm deep).",
  loss: "Stiffness loss: how much stiffer the supports should be here, as a percentage of the track's nominal support stiffness (80 kN/mm unless the track says otherwise). 50 % means half the nominal stiffness.",
};

/** A legend in one row or a few under the x-axis title, at any plot height: placed from the
 * figure's bottom edge, not as a fraction of the plot (which lands on the title when a phone
 * makes the plot short); Plotly widens the bottom margin when the rows need it. */
export const LEGEND_BELOW = { orientation: "h", x: 0, y: 0, yref: "container", yanchor: "bottom" };

/** A base layout: chainage on x, readable fonts, legend below the axis title. */
export function baseLayout(extra = {}) {
  return {
    margin: { l: 64, r: 24, t: 36, b: 96 },
    font: { family: "system-ui, -apple-system, 'Segoe UI', Roboto, sans-serif", size: 13, color: "#1b1f24" },
    paper_bgcolor: "#ffffff",
    plot_bgcolor: "#ffffff",
    hovermode: "x unified",
    legend: LEGEND_BELOW,
    xaxis: { title: { text: "Chainage (m)" }, showgrid: true, gridcolor: "#e3e6ea", zeroline: false },
    yaxis: { title: { text: "Loaded level (mm)" }, showgrid: true, gridcolor: "#e3e6ea", zerolinecolor: "#9aa3ad", automargin: true },
    ...extra,
  };
}

// Only SVG traces are used: WebGL traces (scattergl) compile code at run time, which the
// service's Content-Security-Policy (script-src 'self') forbids. The server decimates instead.

/** Rectangles shading each soft spot over the full plot height (layout.shapes). */
export function softSpotShapes(spots, { fill = COLORS.spotFill, line = COLORS.spotLine, name = "soft-spot" } = {}) {
  return spots.map((s) => ({
    type: "rect",
    xref: "x",
    yref: "paper",
    x0: s.start_m,
    x1: s.end_m,
    y0: 0,
    y1: 1,
    fillcolor: fill,
    line: { color: line, width: 1, dash: "dot" },
    layer: "below",
    name,
  }));
}

/** One text label per soft spot (layout.annotations): number, depth and stiffness loss. */
export function softSpotLabels(spots, { prefix = "S", color = COLORS.spotLine, widthPx = null, range = null } = {}) {
  const labels = spots.map((s, i) => ({
    x: s.peak_m ?? (s.start_m + s.end_m) / 2,
    xref: "x",
    y: 1,
    yref: "paper",
    yanchor: "bottom",
    showarrow: false,
    // One convention everywhere: a loss is a positive percentage of the nominal stiffness.
    text: `${prefix}${i + 1}: ${Number(s.depth_mm).toFixed(2)} mm deep, ${Number(s.stiffness_loss_pct).toFixed(0)} % loss`,
    font: { size: 11, color: "#1b1f24" },
    bgcolor: "rgba(255,255,255,0.85)",
    bordercolor: color,
    borderwidth: 1,
    borderpad: 2,
    name: "soft-spot-label",
  }));
  if (!widthPx || !range || !(range[1] > range[0])) {
    labels.forEach((a, i) => { a.y = 1 + (i % 2) * LABEL_ROW; });
    return labels;
  }
  // Laid out in the plot's own pixels: on a narrow plot a label is its name only (the rest
  // is its hover text and the table's row), each goes to the first row where it overlaps no
  // other, and a label that finds no row is left out (its peak marker still says it all).
  const short = widthPx < SHORT_LABELS_BELOW_PX;
  const rowsEnd = Array(LABEL_ROWS).fill(-Infinity);
  const order = labels.map((a, i) => i).sort((i, j) => labels[i].x - labels[j].x);
  const kept = [];
  for (const i of order) {
    const a = labels[i];
    if (short) {
      a.hovertext = a.text;
      a.text = `${prefix}${i + 1}`;
    }
    const w = a.text.length * LABEL_CHAR_PX + 2 * (a.borderpad + a.borderwidth) + 4;
    const mid = ((a.x - range[0]) / (range[1] - range[0])) * widthPx;
    const row = rowsEnd.findIndex((end) => mid - w / 2 > end + LABEL_GAP_PX);
    if (row < 0) continue;
    rowsEnd[row] = mid + w / 2;
    a.y = 1 + row * LABEL_ROW;
    kept.push(a);
  }
  return kept;
}

const LABEL_ROW = 0.075; // paper height between label rows
const LABEL_ROWS = 2; // rows the plot's top margin holds
const LABEL_CHAR_PX = 6.6; // width of a character of the 11 px label font, px (generous)
const LABEL_GAP_PX = 4;
const SHORT_LABELS_BELOW_PX = 640; // plot width below which labels are names only

/** Keyboard-accessible zoom/pan buttons for a chainage plot (Plotly's modebar is mouse-only). */
export function zoomControls(gd, { label = "Plot view" } = {}) {
  const P = plotly();
  const range = () => {
    const r = gd.layout.xaxis.range;
    return [Number(r[0]), Number(r[1])];
  };
  const setRange = (a, b) => P.relayout(gd, { "xaxis.range": [a, b], "xaxis.autorange": false });
  const zoom = (factor) => {
    const [a, b] = range();
    const mid = (a + b) / 2;
    const half = ((b - a) / 2) * factor;
    setRange(mid - half, mid + half);
  };
  const pan = (frac) => {
    const [a, b] = range();
    const d = (b - a) * frac;
    setRange(a + d, b + d);
  };
  return h("div", { class: "plot-controls", role: "group", "aria-label": label },
    h("button", { type: "button", class: "button small", onclick: () => zoom(0.5), "aria-label": "Zoom in" }, "Zoom in"),
    h("button", { type: "button", class: "button small", onclick: () => zoom(2), "aria-label": "Zoom out" }, "Zoom out"),
    h("button", { type: "button", class: "button small", onclick: () => pan(-0.4), "aria-label": "Pan towards lower chainage" }, "◀ Pan"),
    h("button", { type: "button", class: "button small", onclick: () => pan(0.4), "aria-label": "Pan towards higher chainage" }, "Pan ▶"),
    h("button", {
      type: "button", class: "button small",
      onclick: () => P.relayout(gd, { "xaxis.autorange": true, "yaxis.autorange": true }),
    }, "Reset view"),
  );
}

/** Zoom a plot's x axis to a window around [a, b]. */
export function zoomTo(gd, a, b, margin = 0.75) {
  const w = Math.max(b - a, 1);
  plotly().relayout(gd, { "xaxis.range": [a - w * margin - 5, b + w * margin + 5], "xaxis.autorange": false });
}

/** Viridis sample (0..1) as an rgb string, for lines coloured by order (e.g. run date). */
export function viridis(t) {
  const stops = [
    [0.0, [68, 1, 84]], [0.25, [59, 82, 139]], [0.5, [33, 145, 140]], [0.75, [94, 201, 98]], [1.0, [253, 231, 37]],
  ];
  const x = Math.max(0, Math.min(1, t));
  for (let i = 1; i < stops.length; i += 1) {
    if (x <= stops[i][0]) {
      const [x0, c0] = stops[i - 1];
      const [x1, c1] = stops[i];
      const f = (x - x0) / (x1 - x0);
      const c = c0.map((v, k) => Math.round(v + (c1[k] - v) * f));
      return `rgb(${c[0]}, ${c[1]}, ${c[2]})`;
    }
  }
  return "rgb(253, 231, 37)";
}

/** Resize every Plotly graph inside an element (after it becomes visible). */
export function resizeAll(root) {
  if (!window.Plotly) return;
  for (const gd of root.querySelectorAll(".js-plotly-plot")) window.Plotly.Plots.resize(gd);
}
