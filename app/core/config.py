"""Service settings, read from the environment (pydantic-settings).

Every setting has an environment variable ``TRACKPROFILE_<NAME>`` (e.g.
``TRACKPROFILE_MAX_UPLOAD_MB=200``); the database URL is also read from ``DATABASE_URL``.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Annotated

from pydantic import AliasChoices, Field, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from app.core.memory import RELEASE_AFTER_IDLE_S
from app.core.scopes import format_scopes, parse_scopes

REPO_ROOT = Path(__file__).resolve().parents[2]
"""The project checkout (``app/`` and ``static/``, ``migrations/`` beside it)."""


class Settings(BaseSettings):
    """Configuration of one service instance.

    Attributes
    ----------
    data_dir : Path
        Where the embedded SQLite database lives (``./data`` unless ``TRACKPROFILE_DATA_DIR``).
    database_url : str or None
        SQLAlchemy URL (``DATABASE_URL``); default ``sqlite:///<data_dir>/trackprofile.db``.
    max_upload_mb : float
        Largest accepted run upload (``POST /api/v1/runs``), MB (10^6 bytes); larger uploads
        get 413 and store nothing. The memory an upload takes while it is read and checked is
        a small multiple of this (see docs/benchmarks.md).
    max_body_kb : float
        Largest accepted body of every other request (JSON objects, the CSV preview), kB.
    require_api_key : bool
        When true, every write (POST/DELETE under ``/api/v1``) needs a valid API key.
    require_api_key_for_reads : bool
        When true, reads need a key too (and so do writes, even if ``require_api_key`` was
        left false: closing reads alone would be a mistake; a warning is logged); by default
        the dashboard reads without one.
    public_docs : bool
        When reads need a key, whether ``/docs`` and ``/openapi.json`` are open all the same
        (false, the default: a service that closed its reads shows nothing without a key,
        not even the list of its routes; true publishes the API's description to
        integrators). Where reads are open the docs are open too.
    default_key_scopes : str
        Scopes of a key made by ``python -m app create-key`` without ``--scopes``
        (comma-separated: ``read``, ``write``, ``admin``; see :mod:`app.core.scopes`). The
        default, every scope, is what keys could do before scopes existed.
    read_only : bool
        Refuse every write with 403 (a read-only replica or a public dashboard).
    cors_origins : list of str
        Origins allowed by CORS; empty (the default) turns CORS off. Comma-separated in the env.
    workers : int
        Background processing threads per app process (also caps concurrent inversions).
    inline_max_samples : int
        Logs with at most this many samples are processed inside the upload request (the
        answer already carries the result); longer ones go to the background worker.
    processing_budget_s : float
        Longest wall time the inversion of one run may take, s; a run that takes longer fails
        with ``"kind": "BudgetExceeded"`` (checked between the engine's stages) and frees its
        processing slot for the next run.
    poll_interval_s : float
        How often an idle worker looks for queued runs in the database, s.
    lease_s : float
        A run claimed by a worker whose heartbeat is older than this is taken over, s.
    max_attempts : int
        A run whose processing was interrupted this many times is marked failed.
    wait_timeout_s : float
        Longest time ``POST /api/v1/runs?wait=true`` waits for the result, s.
    simulate_max_duration_s : float
        Longest simulated run ``POST /api/v1/simulate`` accepts, s of travel.
    static_dir : Path
        The dashboard's files, served at ``/static`` (``index.html`` at ``/``).
    plotly_dashboard_js : Path
        plotly.js with only the dashboard's trace types (core and heatmap), bundled by
        ``scripts/serve.sh`` and ``scripts/test.sh`` from npm: served to the dashboard when
        present and of the plotly package's plotly.js version, else ``plotly_partial_js``.
    plotly_partial_js : Path
        plotly's partial bundle (npm ``plotly.js-cartesian-dist-min``, installed by the same
        scripts when the first cannot be built): served when present and of the plotly
        package's plotly.js version, else the package's full bundle.
    run_migrations : bool
        Apply the Alembic migrations when the app starts.
    start_worker : bool
        Start the background worker threads with the app.
    memory_release_idle_s : float
        Memory freed by the service's work is kept in the process while it is busy and handed
        back after this many seconds without work (``app.core.memory``: the next long run
        then reuses pages instead of faulting them in again); 0 hands it back after every run
        and keeps the C allocator's defaults.
    freeze_startup_heap : bool
        After start-up, collect garbage once and move the start-up heap out of the garbage
        collector's reach (``gc.freeze``), so full collections scan only request garbage. The
        collection takes ~0.25 s; a process that starts many apps (the tests) may skip it.
    auto_calibrate_runs : int
        Calibrate a vehicle automatically once it has this many new processed runs (0, the
        default: never); the result is applied only when it is significant.
    detail_retention_days : float or None
        A processed run's detail (profile, signals, log) is removed this many days after its
        recording (``app.services.storage.retention``); None (the default): kept for ever. Its
        metadata, soft spots and share of the track's aggregate are always kept.
    detail_retention_runs : int or None
        Only the newest this many processed runs of each track keep their detail; None (the
        default): all.
    log_retention_runs : int or None
        Only the newest this many processed runs of each vehicle keep their stored log (what
        reprocessing with new vehicle parameters and calibration read), at least
        ``auto_calibrate_runs``; None: every run with detail. Default 20: a 1 kHz log is
        ~0.6 MB per km even compressed, ten times the rest of a run.
    retention_interval_s : float
        How often an idle worker sweeps expired detail, s.
    """

    model_config = SettingsConfigDict(
        env_prefix="TRACKPROFILE_", populate_by_name=True, extra="ignore"
    )

    data_dir: Path = Path("data")
    database_url: str | None = Field(
        default=None,
        validation_alias=AliasChoices("DATABASE_URL", "TRACKPROFILE_DATABASE_URL", "database_url"),
    )
    max_upload_mb: float = Field(default=512.0, gt=0)
    max_body_kb: float = Field(default=1024.0, gt=0)
    require_api_key: bool = False
    require_api_key_for_reads: bool = False
    public_docs: bool = False
    default_key_scopes: str = "read,write,admin"
    read_only: bool = False
    cors_origins: Annotated[list[str], NoDecode] = Field(default_factory=list)
    workers: int = Field(default=1, ge=1, le=16)
    inline_max_samples: int = Field(default=300_000, ge=0)
    processing_budget_s: float = Field(default=600.0, gt=0)
    poll_interval_s: float = Field(default=1.0, gt=0)
    lease_s: float = Field(default=60.0, gt=0)
    max_attempts: int = Field(default=3, ge=1)
    wait_timeout_s: float = Field(default=300.0, gt=0)
    simulate_max_duration_s: float = Field(default=120.0, gt=0)
    static_dir: Path = REPO_ROOT / "static"
    plotly_dashboard_js: Path = REPO_ROOT / ".cache/plotly/plotly-dashboard.min.js"
    plotly_partial_js: Path = (
        REPO_ROOT
        / ".cache/plotly/node_modules/plotly.js-cartesian-dist-min"
        / "plotly-cartesian.min.js"
    )
    run_migrations: bool = True
    start_worker: bool = True
    memory_release_idle_s: float = Field(default=RELEASE_AFTER_IDLE_S, ge=0, le=3600)
    freeze_startup_heap: bool = True
    auto_calibrate_runs: int = Field(default=0, ge=0, le=10_000)
    detail_retention_days: float | None = Field(default=None, gt=0)
    detail_retention_runs: int | None = Field(default=None, ge=1)
    log_retention_runs: int | None = Field(default=20, ge=1)
    retention_interval_s: float = Field(default=60.0, gt=0)

    @field_validator("cors_origins", mode="before")
    @classmethod
    def _split_origins(cls, value: object) -> object:
        if isinstance(value, str):
            return [v.strip() for v in value.split(",") if v.strip()]
        return value

    @field_validator("default_key_scopes")
    @classmethod
    def _known_scopes(cls, value: str) -> str:
        return format_scopes(parse_scopes(value))

    @property
    def sqlalchemy_url(self) -> str:
        """The database URL in force (``database_url`` or the SQLite file under ``data_dir``)."""
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'trackprofile.db').resolve()}"

    @property
    def max_upload_bytes(self) -> int:
        """Upload size limit, bytes."""
        return int(self.max_upload_mb * 1_000_000)

    @property
    def max_body_bytes(self) -> int:
        """Size limit of every body but a run upload, bytes."""
        return int(self.max_body_kb * 1_000)


@lru_cache
def get_settings() -> Settings:
    """Settings from the environment, read once per process."""
    return Settings()
