# Sourced by serve.sh and test.sh after _venv.sh: plotly's partial "cartesian" bundle (npm
# plotly.js-cartesian-dist-min, 1.5 MB instead of the full 4.8 MB: every trace type the
# dashboard draws) at the plotly.js version of the installed plotly package, into
# .cache/plotly. The service serves it when present (app/web.py) and falls back to the plotly
# package's full bundle otherwise: a first visit then waits seconds longer for its first chart.
# Fetched here, at install time, only when missing or of another version; nothing at run time.

plotly_js_version="$(python -c 'import plotly.offline; print(plotly.offline.get_plotlyjs_version())')"
plotly_partial=".cache/plotly/node_modules/plotly.js-cartesian-dist-min"
if ! head -c 400 "$plotly_partial/plotly-cartesian.min.js" 2>/dev/null | grep -q " v${plotly_js_version}\b"; then
  if command -v npm >/dev/null 2>&1; then
    echo "installing plotly.js-cartesian-dist-min@${plotly_js_version} (npm) for the dashboard's charts"
    # Its own prefix: npm removes from a prefix what the install at hand does not name.
    npm install --no-save --no-audit --no-fund --no-package-lock --prefix .cache/plotly \
      "plotly.js-cartesian-dist-min@${plotly_js_version}" >/dev/null \
      || echo "warning: plotly.js-cartesian-dist-min could not be installed: the dashboard serves the full plotly.js (slower first charts)" >&2
  else
    echo "warning: npm is missing: the dashboard serves the full plotly.js (slower first charts)" >&2
  fi
fi
