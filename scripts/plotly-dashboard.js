// plotly.js with only what the dashboard draws, bundled at install time by scripts/_plotly.sh
// (esbuild, from the npm package plotly.js): its core (scatter, shapes, annotations, legend,
// hover, modebar) and the heatmap trace. Chromium evaluates it in about half the time of the
// partial "cartesian" bundle (which adds bar, box, contour, histograms, pie, violin, image and
// the world calendars), which a cold first visit's chart waits for (docs/benchmarks.md, issue
// 14). A trace type added to static/js must be registered here (test_first_use.py checks).
var Plotly = require("plotly.js/lib/core");

Plotly.register([require("plotly.js/lib/heatmap")]);

module.exports = Plotly;
