// Hash router of the dashboard: #/ (runs & tracks), #/upload, #/runs/{id}, #/tracks/{name},
// #/simulate, #/vehicles, #/vehicles/{name}. Each page module exports render(main, params) and
// may return a cleanup function.

import { h, clear, announce } from "./dom.js";
import { loadPlotly } from "./plots.js";
import * as home from "./pages/home.js";
import * as upload from "./pages/upload/index.js";
import * as run from "./pages/run.js";
import * as track from "./pages/track/index.js";
import * as simulate from "./pages/simulate.js";
import * as vehicle from "./pages/vehicle.js";

const routes = [
  { pattern: /^\/?$/, page: home, nav: "home", title: "Runs & tracks" },
  { pattern: /^\/upload\/?$/, page: upload, nav: "upload", title: "Upload a run" },
  { pattern: /^\/runs\/([^/]+)\/?$/, page: run, charts: true, nav: "home", title: "Run" },
  { pattern: /^\/tracks\/([^/]+)\/?$/, page: track, charts: true, nav: "home", title: "Track" },
  { pattern: /^\/simulate\/?$/, page: simulate, charts: true, nav: "simulate", title: "Simulate" },
  { pattern: /^\/vehicles\/?$/, page: vehicle, nav: "vehicles", title: "Vehicles" },
  { pattern: /^\/vehicles\/([^/]+)\/?$/, page: vehicle, nav: "vehicles", title: "Vehicle" },
];

let cleanup = null;
let firstRender = true;

function parseHash() {
  const raw = window.location.hash.replace(/^#/, "") || "/";
  const [path, query = ""] = raw.split("?");
  return { path, query: new URLSearchParams(query) };
}

async function render() {
  const main = document.getElementById("main");
  const { path, query } = parseHash();
  if (typeof cleanup === "function") {
    try {
      cleanup();
    } catch (err) {
      console.error(err);
    }
  }
  cleanup = null;
  clear(main);
  const route = routes.find((r) => r.pattern.test(path));
  for (const link of document.querySelectorAll("[data-nav]")) {
    if (route && link.dataset.nav === route.nav) link.setAttribute("aria-current", "page");
    else link.removeAttribute("aria-current");
  }
  if (!route) {
    main.appendChild(h("h1", {}, "Page not found"));
    main.appendChild(h("p", {}, h("a", { href: "#/" }, "Back to runs and tracks")));
    return;
  }
  // Pages with charts start fetching plotly.js now, alongside their own data.
  if (route.charts) loadPlotly().catch(() => {});
  const params = path.match(route.pattern).slice(1).map((p) => decodeURIComponent(p));
  document.title = `${route.title} — TrackProfile`;
  try {
    cleanup = await route.page.render(main, params, query);
  } catch (err) {
    console.error(err);
    main.appendChild(h("div", { class: "message error", role: "alert" }, `This page failed to load: ${err.message}`));
  }
  if (!firstRender) {
    // Move focus to the new page so keyboard and screen-reader users start at its top.
    main.focus({ preventScroll: false });
    announce(document.title);
  }
  firstRender = false;
}

window.addEventListener("hashchange", render);
if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", render);
} else {
  render();
}
