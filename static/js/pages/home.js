// Home: the tracks (each opens its chainage map) and the latest runs (each opens its run view).

import { h, clear, announce, field, fmt, fmtDate, fmtKmRange, messageBox, plural, scrollTable } from "../dom.js";
import { ApiError, apiFetch, apiPostJson } from "../api.js";
import { evidenceOf, LEVEL_LABELS } from "../register.js";
import { loadPlotly } from "../plots.js";
import { provisionalLabel } from "../provisional.js";

const PAGE = 50;

export async function render(main) {
  main.appendChild(h("h1", {}, "Runs and tracks"));
  main.appendChild(h("p", { class: "lead", id: "intro" },
    "TrackProfile turns what an ordinary train's sensors logged (vertical acceleration and pitch rate) into the ",
    h("dfn", { title: "The rail level under the passing wheels, in mm: where the track gives way under load, it dips." }, "loaded profile"),
    " of the track, and finds its soft spots: places where the supports have lost stiffness."));
  main.appendChild(h("p", { class: "hint", id: "first-step" },
    "First step: ", h("a", { href: "#/upload" }, "upload a run log"),
    " (no log at hand? the repository has one: examples/example_run.csv.gz, start chainage 24.13 m) with the ",
    h("dfn", { title: "The chainage (distance along the line, in m) where the log starts." }, "start chainage"),
    " where it begins, or ", h("a", { href: "#/simulate" }, "simulate a run"), "."));
  const status = messageBox("info");
  main.appendChild(status.el);

  const tracksSection = h("section", { class: "card", "aria-labelledby": "tracks-h" }, h("h2", { id: "tracks-h" }, "Tracks"));
  const runsSection = h("section", { class: "card", "aria-labelledby": "runs-h" },
    h("div", { class: "section-head" }, h("h2", { id: "runs-h" }, "Latest runs"), h("a", { class: "button primary", href: "#/upload" }, "Upload a run")));
  main.append(h("div", { class: "home-grid" }, tracksSection, runsSection));
  const attention = h("section", { class: "card", "aria-labelledby": "attention-h", id: "attention" },
    h("h2", { id: "attention-h" }, "Needs attention"),
    h("p", { class: "muted", id: "attention-body" }, "Reading the tracks' registers…"));
  main.insertBefore(attention, main.querySelector(".home-grid"));
  main.appendChild(newTrackCard());

  let tracks = [];
  let tracksTotal = 0;
  let runs = [];
  let total = 0;
  try {
    const [trackAnswer, runAnswer] = await Promise.all([
      apiFetch(`tracks?limit=${PAGE}`),
      apiFetch(`runs?limit=${PAGE}`),
    ]);
    tracks = trackAnswer.data;
    tracksTotal = trackAnswer.count;
    runs = runAnswer.data;
    total = typeof runAnswer.count === "number" ? runAnswer.count : runs.length;
  } catch (err) {
    status.show(`Cannot load the data: ${err.message}`, "error");
    return null;
  }

  fillAttention(attention, tracks);
  if (tracks.length === 0) {
    tracksSection.appendChild(h("p", {}, "No track yet. ", h("a", { href: "#/upload" }, "Upload a run"), " or ", h("a", { href: "#/simulate" }, "simulate one"), " to start."));
  } else {
    const list = h("ul", { class: "track-list", id: "track-list" });
    const addTracks = (items) => {
      for (const t of items) {
        const count = t.n_runs;
        list.appendChild(h("li", {},
          h("a", { href: `#/tracks/${encodeURIComponent(t.id)}`, class: "track-link" }, t.name),
          count !== undefined ? h("span", { class: "muted" }, ` · ${plural(count, "run")}`) : null,
          t.description ? h("p", { class: "muted small" }, t.description) : null));
      }
    };
    addTracks(tracks);
    tracksSection.appendChild(list);
    // Tracks come a page at a time (the list is sorted by name on the server).
    const moreTracks = h("button", { type: "button", class: "button secondary", id: "more-tracks", hidden: tracks.length >= tracksTotal }, "Show more tracks");
    moreTracks.addEventListener("click", async () => {
      try {
        const next = (await apiFetch(`tracks?limit=${PAGE}&offset=${tracks.length}`)).data;
        tracks = tracks.concat(next);
        addTracks(next);
        moreTracks.hidden = tracks.length >= tracksTotal || next.length === 0;
      } catch (err) {
        status.show(`Cannot load more tracks: ${err.message}`, "error");
      }
    });
    tracksSection.appendChild(moreTracks);
  }

  const tbody = h("tbody", {});
  const table = scrollTable("Latest runs", h("table", { class: "data", id: "runs-table" },
    h("caption", { class: "visually-hidden" }, "Latest runs"),
    h("thead", {}, h("tr", {},
      h("th", { scope: "col" }, "Run"), h("th", { scope: "col" }, "Track"), h("th", { scope: "col" }, "Vehicle"),
      h("th", { scope: "col" }, "Recorded"), h("th", { scope: "col", class: "num" }, "Start (m)"),
      h("th", { scope: "col" }, "Status"), h("th", { scope: "col" }, h("span", { class: "visually-hidden" }, "Actions")))),
    tbody));
  let update = () => {};
  const fill = (items) => {
    clear(tbody);
    for (const r of items) {
      const id = r.id;
      const del = h("button", {
        type: "button", class: "button small danger", "aria-label": `Delete run ${id}`,
        onclick: async () => {
          // eslint-disable-next-line no-alert
          if (!window.confirm(`Delete run ${id} and its profile? This cannot be undone.`)) return;
          try {
            await apiFetch(`runs/${encodeURIComponent(id)}`, { method: "DELETE" });
            runs = runs.filter((x) => x.id !== id);
            total -= 1;
            fill(runs);
            update();
            announce(`Run ${id} deleted.`);
          } catch (err) {
            status.show(`Cannot delete run ${id}: ${err.message}`, "error");
          }
        },
      }, "Delete");
      tbody.appendChild(h("tr", {},
        h("th", { scope: "row" }, h("a", { href: `#/runs/${encodeURIComponent(id)}` }, `Run ${id}`)),
        h("td", {}, h("a", { href: `#/tracks/${encodeURIComponent(r.track_id)}` }, r.track)),
        h("td", {}, h("a", { href: `#/vehicles/${encodeURIComponent(r.vehicle)}` }, r.vehicle)),
        h("td", {}, fmtDate(r.recorded_at)),
        h("td", { class: "num" }, fmt(r.start_chainage_m, 1)),
        h("td", {}, h("span", { class: `status status-${r.status}`, title: r.status === "failed" && r.error ? String(r.error.message || r.error) : "" }, r.status)),
        h("td", {}, del)));
    }
  };
  if (runs.length === 0) {
    runsSection.appendChild(h("p", { class: "muted" }, "No run yet."));
  } else {
    fill(runs);
    runsSection.appendChild(table);
    const more = h("button", { type: "button", class: "button secondary", id: "more-runs" }, "Show more runs");
    const counter = h("p", { class: "hint", id: "runs-count" });
    update = () => {
      counter.textContent = `${runs.length} of ${plural(total, "run")} shown.`;
      more.hidden = runs.length >= total;
    };
    more.addEventListener("click", async () => {
      try {
        const next = (await apiFetch(`runs?limit=${PAGE}&offset=${runs.length}`)).data;
        runs = runs.concat(next);
        fill(runs);
        update();
        announce(`${next.length} more runs shown.`);
      } catch (err) {
        status.show(`Cannot load more runs: ${err.message}`, "error");
      }
    });
    update();
    runsSection.append(counter, more);
  }
  // The content is shown without plotly.js (performance mark "home-content": the first-paint
  // timing of the browser tests). Only then, when the browser is idle, plotly.js is fetched
  // and compiled for the chart the user is likely to open next (a run or a track).
  performance.mark("home-content");
  if (tracks.length || runs.length) {
    const idle = window.requestIdleCallback || ((fn) => setTimeout(fn, 300));
    idle(() => loadPlotly().catch(() => {}), { timeout: 1500 });
  }
  return null;
}

const ATTENTION_ROWS = 12;

/** Across tracks: the defects at a limit level, most urgent first (each track's register). */
async function fillAttention(section, tracks) {
  const body = section.querySelector("#attention-body");
  const found = [];
  await Promise.all(tracks.map(async (t) => {
    try {
      const defects = await apiFetch(`/api/v1/tracks/${encodeURIComponent(t.id)}/defects`);
      for (const d of defects) if (d.level) found.push({ ...d, track: t });
    } catch {
      // a track whose register cannot be read is left out here; its own page says why
    }
  }));
  if (!found.length) {
    body.textContent = tracks.length ? "No defect of any track has reached a limit." : "No track yet.";
    return;
  }
  found.sort((a, b) => a.priority - b.priority || b.depth_mm - a.depth_mm);
  const rows = found.slice(0, ATTENTION_ROWS).map((d) => h("tr", {},
    h("td", { class: `level level-${d.level}` }, LEVEL_LABELS[d.level]),
    h("td", {}, h("a", { href: `#/tracks/${encodeURIComponent(d.track.id)}` }, d.track.name)),
    h("td", { class: "num" }, fmtKmRange(d.start_m, d.end_m)),
    h("td", { class: "num" }, fmt(d.depth_mm, 2)),
    h("td", { class: "num" }, fmt(d.stiffness_loss_pct, 0)),
    // as in the register: a separated defect resting on unknown vehicles says so here too
    h("td", {}, evidenceOf(d), provisionalLabel(d))));
  body.replaceWith(
    h("p", { class: "small", id: "attention-count" }, `${plural(found.length, "defect")} at a limit level across ${plural(new Set(found.map((d) => d.track.id)).size, "track")}${found.length > ATTENTION_ROWS ? `; the ${ATTENTION_ROWS} most urgent:` : ":"}`),
    scrollTable("Defects needing attention",
      h("table", { class: "data", id: "attention-table" },
        h("thead", {}, h("tr", {}, ["Level", "Track", "Zone", "Depth (mm)", "Loss (%)", "Evidence"].map((t, i) => h("th", { scope: "col", class: i >= 2 && i <= 4 ? "num" : null }, t)))),
        h("tbody", {}, rows))));
}

/** A new track by name, then its page: where its centerline is uploaded (GNSS placement). */
function newTrackCard() {
  const name = h("input", { type: "text", id: "new-track-name", maxlength: 200, required: true, autocomplete: "off" });
  const desc = h("input", { type: "text", id: "new-track-description", maxlength: 500 });
  const msg = messageBox("info");
  const form = h("form", { id: "new-track-form" },
    h("div", { class: "grid-2" }, field("Track name", name), field("Description (optional)", desc)),
    h("div", { class: "actions" }, h("button", { type: "submit", class: "button secondary", id: "new-track-create" }, "Create the track")),
    msg.el);
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    const n = name.value.trim();
    if (!n) {
      msg.show("Give the track a name.", "error");
      name.focus();
      return;
    }
    try {
      const t = await apiPostJson("tracks", { name: n, ...(desc.value.trim() ? { description: desc.value.trim() } : {}) });
      window.location.hash = `#/tracks/${encodeURIComponent(t.id)}`;
    } catch (err) {
      msg.show(err instanceof ApiError ? `Not created: ${err.message}` : String(err), "error");
    }
  });
  return h("section", { class: "card", "aria-labelledby": "new-track-h" },
    h("h2", { id: "new-track-h" }, "New track"),
    h("p", { class: "hint" }, "Create a track before its first run — for instance to give it its centerline, so that runs with GNSS fixes are placed without a start chainage. Its page opens with the centerline upload."),
    form);
}
