# TrackProfile service: uvicorn app.main:app on port 8000, database in the /data volume.

# plotly's partial bundle for the dashboard's charts (npm, at build time; scripts/_plotly.sh
# does the same for serve.sh/test.sh). It must be the plotly.js version of the plotly package
# pip installs below (python -c "import plotly.offline; print(plotly.offline.get_plotlyjs_version())");
# if not, the service logs a warning and serves the package's full bundle (slower first charts).
FROM node:20-slim AS plotly-partial
ARG PLOTLY_JS_VERSION=4.1.1
RUN npm install --no-save --no-audit --no-fund --no-package-lock --prefix /opt/plotly \
    "plotly.js-cartesian-dist-min@${PLOTLY_JS_VERSION}"

FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    TRACKPROFILE_DATA_DIR=/data

RUN groupadd --system --gid 10001 app \
    && useradd --system --uid 10001 --gid app --home-dir /app --shell /usr/sbin/nologin app

WORKDIR /app
COPY pyproject.toml README.md alembic.ini ./
COPY engine ./engine
COPY app ./app
COPY migrations ./migrations
COPY static ./static
COPY --from=plotly-partial /opt/plotly/node_modules/plotly.js-cartesian-dist-min \
     ./.cache/plotly/node_modules/plotly.js-cartesian-dist-min
# Editable install: the app finds migrations/ and static/ next to its package. The postgres
# extra (psycopg 3) lets DATABASE_URL point at PostgreSQL (see docker-compose.yml).
RUN pip install -e ".[postgres]" \
    && mkdir -p /data \
    && chown app:app /data

USER app
VOLUME ["/data"]
EXPOSE 8000

HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status == 200 else 1)"]

CMD ["uvicorn", "app.main:app", "--host", "0.0.0.0", "--port", "8000", "--proxy-headers", \
     "--timeout-keep-alive", "5", "--limit-concurrency", "256"]
