// Hash router of the dashboard: #/ (runs & tracks), #/upload, #/runs/{id}, #/tracks/{name},
// #/tracks/{name}/quality,
// #/simulate, #/vehicles, #/vehicles/{name}. Each page module exports render(main, params) and
// may return a cleanup function.
//
// A page's module (and what it imports) is loaded when the page is first shown, not before:
// the shell's own graph is this file, dom.js and plots.js, so a page with charts starts
// fetching plotly.js after those three and loads its module, its data and plotly.js at the
// same time (a cold first visit's chart waits for the longest of them, not for their sum:
// docs/benchmarks.md, issue 14).

import { h, clear, announce } from "./dom.js";
import { loadPlotly } from "./plots.js";

const home = () => import("./pages/home.js");
const vehicle = () => import("./pages/vehicle.js");
const routes = [
  { pattern: /^\/?$/, page: home, nav: "home", title: "Runs & tracks" },
  { pattern: /^\/upload\/?$/, page: () => import("./pages/upload/index.js"), nav: "upload", title: "Upload a run" },
  { pattern: /^\/runs\/([^/]+)\/?$/, page: () => import("./pages/run.js"), charts: true, nav: "home", title: "Run" },
  { pattern: /^\/tracks\/([^/]+)\/?$/, page: () => import("./pages/track/index.js"), charts: true, nav: "home", title: "Track" },
  { pattern: /^\/tracks\/([^/]+)\/quality\/?$/, page: () => import("./pages/quality.js"), charts: true, nav: "home", title: "Track quality" },
  { pattern: /^\/simulate\/?$/, page: () => import("./pages/simulate.js"), charts: true, nav: "simulate", title: "Simulate" },
  { pattern: /^\/vehicles\/?$/, page: vehicle, nav: "vehicles", title: "Vehicles" },
  { pattern: /^\/vehicles\/([^/]+)\/?$/, page: vehicle, nav: "vehicles", title: "Vehicle" },
];

let cleanup = null;
let firstRender = true;
let rendered = 0; // the latest render's ticket: a page whose module arrives late is not drawn

function parseHash() {
  const raw = window.location.hash.replace(/^#/, "") || "/";
  const [path, query = ""] = raw.split("?");
  return { path, query: new URLSearchParams(query) };
}

async function render() {
  const ticket = ++rendered;
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
  // Pages with charts start fetching plotly.js now, alongside their module and data.
  if (route.charts) loadPlotly().catch(() => {});
  const params = path.match(route.pattern).slice(1).map((p) => decodeURIComponent(p));
  document.title = `${route.title} — TrackProfile`;
  try {
    const page = await route.page();
    if (rendered !== ticket) return; // another page was asked for while this one loaded
    cleanup = await page.render(main, params, query);
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
