// A classic script run before the dashboard's modules (index.html): on a chart page (run,
// track, simulate) it starts fetching plotly.js at once, while the shell's module graph
// (app.js, dom.js, plots.js) and the page's module load, instead of after the shell asked for
// it. The preloaded bytes wait in the browser's memory cache until plots.js's loadPlotly()
// inserts the script (the same URL), so other pages (home: content first) pay nothing and a
// chart page's evaluation of plotly.js still starts where it did (docs/benchmarks.md, issue 14).
// The routes are those of app.js with `charts: true`.
(function () {
  var CHART_ROUTES = /^#\/(runs\/[^/]+|tracks\/[^/]+|simulate)\/?(\?|$)/;
  var meta = document.querySelector('meta[name="plotly-src"]');
  if (!meta || !CHART_ROUTES.test(window.location.hash)) return;
  var link = document.createElement("link");
  link.rel = "preload";
  link.as = "script";
  link.href = meta.content;
  document.head.appendChild(link);
})();
