# TrackProfile service: uvicorn app.main:app on port 8000, database in the /data volume.

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
# Editable install: the app finds migrations/ and static/ next to its package. The postgres
# extra (psycopg 3) lets DATABASE_URL point at PostgreSQL (see docker-compose.yml).
RUN pip install -e ".[postgres]" \
    && mkdir -p /data \
    && chown app:app /data
# The dashboard's own plotly.js bundle (core, scatter, heatmap), built by the same script as
# serve.sh and test.sh use, at the plotly.js version of the plotly package just installed
# (scripts/_plotly.sh; falls back to plotly's partial bundle, then to the package's full one,
# with a warning). npm is needed only for this step and removed in the same layer.
COPY scripts/_plotly.sh scripts/plotly-dashboard.js ./scripts/
RUN apt-get update \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends npm \
    && bash scripts/_plotly.sh \
    && apt-get purge -y --auto-remove npm \
    && rm -rf /var/lib/apt/lists/* /root/.npm .cache/plotly-build

USER app
VOLUME ["/data"]
EXPOSE 8000

HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status == 200 else 1)"]

CMD ["uvicorn", "app.main:app", "--host", "0.0.0.0", "--port", "8000", "--proxy-headers", \
     "--http", "h11", "--no-server-header", "--timeout-keep-alive", "5", "--limit-concurrency", "256"]
