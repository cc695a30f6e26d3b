# Sourced by serve.sh and test.sh after _venv.sh: the dashboard's plotly.js, at the plotly.js
# version of the installed plotly package, into .cache/plotly (nothing is fetched at run time):
#  1. .cache/plotly/plotly-dashboard.min.js: plotly's core and heatmap only (1.1 MB), bundled
#     here from the npm package plotly.js with esbuild (scripts/plotly-dashboard.js);
#  2. npm plotly.js-cartesian-dist-min (1.5 MB), plotly's partial bundle, when 1 cannot be built.
# The service serves the first of them present at that version (app/web.py) and the plotly
# package's full bundle (4.8 MB) otherwise: a first visit then waits seconds longer for its
# first chart. Done only when missing or of another version.

plotly_js_version="$(python -c 'import plotly.offline; print(plotly.offline.get_plotlyjs_version())')"
plotly_dashboard=".cache/plotly/plotly-dashboard.min.js"
plotly_partial=".cache/plotly/node_modules/plotly.js-cartesian-dist-min"
plotly_at_version() { head -c 400 "$1" 2>/dev/null | grep -q " v${plotly_js_version}\b"; }
if ! plotly_at_version "$plotly_dashboard"; then
  if command -v npm >/dev/null 2>&1; then
    echo "bundling plotly.js ${plotly_js_version} (npm plotly.js and esbuild) for the dashboard's charts"
    # Their own prefixes: npm removes from a prefix what the install at hand does not name.
    build=.cache/plotly-build
    mkdir -p "$build" .cache/plotly
    cp scripts/plotly-dashboard.js "$build/entry.js"
    if npm install --no-save --no-audit --no-fund --no-package-lock --prefix "$build" \
         "plotly.js@${plotly_js_version}" "esbuild@0.28.2" >/dev/null 2>&1 \
       && "$build/node_modules/.bin/esbuild" "$build/entry.js" --bundle --minify --format=iife \
         --global-name=Plotly --target=es2016 --define:global=window --define:define.amd=false \
         --define:process.env.NODE_DEBUG=false --loader:.css=empty --log-level=error \
         --banner:js="/** plotly.js (dashboard: core, scatter, heatmap - minified) v${plotly_js_version} */" \
         --outfile="$plotly_dashboard.tmp" \
       && mv "$plotly_dashboard.tmp" "$plotly_dashboard"; then
      rm -rf "$build"
    else
      rm -f "$plotly_dashboard.tmp"
      echo "warning: plotly.js could not be bundled: the dashboard serves plotly's partial bundle instead" >&2
      plotly_at_version "$plotly_partial/plotly-cartesian.min.js" \
        || npm install --no-save --no-audit --no-fund --no-package-lock --prefix .cache/plotly \
        "plotly.js-cartesian-dist-min@${plotly_js_version}" >/dev/null \
        || echo "warning: plotly.js-cartesian-dist-min could not be installed: the dashboard serves the full plotly.js (slower first charts)" >&2
    fi
  else
    echo "warning: npm is missing: the dashboard serves the full plotly.js (slower first charts)" >&2
  fi
fi
