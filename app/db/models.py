"""ORM models: tracks, vehicles, runs, their per-chainage profile, soft spots and API keys.

Units: SI throughout (N/m, m, kg, s), levels in mm. Profiles are stored as compressed blocks of
1 km of the run's chainage grid, keyed ``(run_id, block)`` so that "run R between chainage a and
b" is one range scan of the primary key over a few rows. Chainage is stored as the engine
computed it from the run's own start chainage; ``Run.chainage_offset_m`` (0 until runs are
aligned) is added when the profile and soft spots are served.
"""

from __future__ import annotations

from dataclasses import fields
from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    Text,
    UniqueConstraint,
    false,
)
from sqlalchemy.orm import Mapped, mapped_column, relationship

from engine.vehicle import VehicleParams
from engine.vehicle_kinds import Vehicle as Vehicle_

from .base import Base, UTCDateTime, utcnow

RUN_STATUSES = ("processing", "done", "failed")
"""Public run states: ``processing`` until the inversion is stored (``done``) or gave up."""

RUN_STAGES = ("queued", "inverting", "storing")
"""What a ``processing`` run is doing: waiting for a worker, in the engine, being written."""

ALIGNMENT_STATUSES = ("reference", "aligned", "placed", "unaligned")
"""How a processed run sits on its track's chainage: the reference of its stretch (nothing was
there before it, offset 0), aligned to the track's aggregated profile, or not alignable (kept
as logged and left out of the aggregate and the register). NULL: not processed yet."""


class Track(Base):
    """A line (or a stretch of one) that runs are recorded on, with its nominal properties."""

    __tablename__ = "tracks"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    description: Mapped[str | None] = mapped_column(Text)
    rail: Mapped[str] = mapped_column(String(50), default="UIC60")
    k_nominal: Mapped[float] = mapped_column(Float)  # N/m per support
    spacing: Mapped[float] = mapped_column(Float)  # m, sleeper spacing
    EI: Mapped[float] = mapped_column("ei", Float)  # N m², rail bending stiffness
    mass_per_m: Mapped[float] = mapped_column(Float)  # kg/m
    c_support: Mapped[float] = mapped_column(Float)  # N s/m per support
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    # chunks whose geometry/stiffness separation waits for a worker (app.services.track.integrate)
    separation_pending_lo: Mapped[int | None] = mapped_column(Integer)
    separation_pending_hi: Mapped[int | None] = mapped_column(Integer)

    runs: Mapped[list[Run]] = relationship(back_populates="track", passive_deletes=True)

    def params_dict(self) -> dict[str, float]:
        """The engine's ``TrackParams`` fields of this track (SI)."""
        return {
            "spacing": self.spacing,
            "EI": self.EI,
            "mass_per_m": self.mass_per_m,
            "k_nominal": self.k_nominal,
            "c_support": self.c_support,
        }


VEHICLE_PARAM_NAMES = tuple(f.name for f in fields(VehicleParams))
"""The engine's ``VehicleParams`` fields, stored one column each."""


class Vehicle(Base):
    """A logging vehicle: the half-car parameter set the inversion needs (SI units)."""

    __tablename__ = "vehicles"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    description: Mapped[str | None] = mapped_column(Text)
    ms: Mapped[float] = mapped_column(Float)  # kg
    Is: Mapped[float] = mapped_column("pitch_inertia", Float)  # kg m²
    mu1: Mapped[float] = mapped_column(Float)  # kg
    mu2: Mapped[float] = mapped_column(Float)  # kg
    ks1: Mapped[float] = mapped_column(Float)  # N/m
    ks2: Mapped[float] = mapped_column(Float)  # N/m
    cs1: Mapped[float] = mapped_column(Float)  # N s/m
    cs2: Mapped[float] = mapped_column(Float)  # N s/m
    kt1: Mapped[float] = mapped_column(Float)  # N/m
    kt2: Mapped[float] = mapped_column(Float)  # N/m
    d1: Mapped[float] = mapped_column(Float)  # m
    d2: Mapped[float] = mapped_column(Float)  # m
    sensor_x_m: Mapped[float] = mapped_column(Float, default=0.0)  # m, ahead of the body CG
    # engine.vehicle_kinds kind; another kind's datasheet values live in kind_params (JSON,
    # with "kind") and the columns above hold its lumped half car
    kind: Mapped[str] = mapped_column(String(20), default="half_car", server_default="half_car")
    kind_params: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    version: Mapped[int] = mapped_column(Integer, default=1)  # current VehicleVersion.version
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)

    def params_dict(self) -> dict[str, Any]:
        """The engine's parameters of this vehicle (SI): the ``VehicleParams`` fields of a
        half car, the kind's own (with ``kind``) otherwise (``engine.vehicle_kinds``)."""
        if self.kind_params is not None and self.kind != "half_car":
            return dict(self.kind_params)
        return {name: float(getattr(self, name)) for name in VEHICLE_PARAM_NAMES}

    def set_params(self, params: Vehicle_) -> None:
        """Store an engine vehicle of any kind in the columns (and ``kind_params``)."""
        self.kind = params.kind
        if isinstance(params, VehicleParams):
            self.kind_params = None
            columns = params
        else:
            self.kind_params = params.to_dict()
            columns = params.lumped_half_car()
        for name, value in columns.to_dict().items():
            setattr(self, name, value)


VERSION_SOURCES = ("created", "manual", "calibration", "restore")
"""What made a vehicle version: registration, a manual edit, an applied calibration, an
earlier version restored."""


class VehicleVersion(Base):
    """One parameter set a vehicle has had (the current one is ``Vehicle.version``).

    Versions are never changed or deleted: a run's ``vehicle_version`` always names the
    parameters its results were computed with.
    """

    __tablename__ = "vehicle_versions"
    __table_args__ = (UniqueConstraint("vehicle_id", "version"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    vehicle_id: Mapped[int] = mapped_column(ForeignKey("vehicles.id", ondelete="CASCADE"))
    version: Mapped[int] = mapped_column(Integer)
    params: Mapped[dict[str, Any]] = mapped_column(JSON)  # the kind's fields (SI), see Vehicle
    source: Mapped[str] = mapped_column(String(20))  # one of VERSION_SOURCES
    calibration_id: Mapped[int | None] = mapped_column(Integer)
    created_by: Mapped[str | None] = mapped_column(String(200))  # API key name, "automatic"
    note: Mapped[str | None] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


CALIBRATION_STATUSES = ("queued", "running", "done", "failed")
"""Stored calibration states (the API shows ``queued`` as ``running``)."""


class Calibration(Base):
    """A calibration of a vehicle from its stored runs (engine.calibration), and its outcome.

    Claimed by the background worker like a run (``claimed_by`` + ``heartbeat_at``); a
    calibration whose worker died is taken over from the start.
    """

    __tablename__ = "calibrations"
    __table_args__ = (
        Index("ix_calibrations_status_heartbeat_at", "status", "heartbeat_at"),
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    vehicle_id: Mapped[int] = mapped_column(
        ForeignKey("vehicles.id", ondelete="CASCADE"), index=True
    )
    status: Mapped[str] = mapped_column(String(12), default="queued")
    request: Mapped[dict[str, Any]] = mapped_column(JSON)  # run_ids, fit, apply, load_kg
    result: Mapped[dict[str, Any] | None] = mapped_column(JSON)  # CalibrationResult.to_dict()
    error: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    applied: Mapped[bool] = mapped_column(Boolean, default=False)
    applied_version: Mapped[int | None] = mapped_column(Integer)
    automatic: Mapped[bool] = mapped_column(Boolean, default=False)
    created_by: Mapped[str | None] = mapped_column(String(200))
    runs_from: Mapped[datetime | None] = mapped_column(UTCDateTime)  # first run's recording
    runs_to: Mapped[datetime | None] = mapped_column(UTCDateTime)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    claimed_by: Mapped[str | None] = mapped_column(String(120))
    heartbeat_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    attempts: Mapped[int] = mapped_column(Integer, default=0)


class Run(Base):
    """One uploaded (or simulated) pass of a vehicle over a track, and its processing state."""

    __tablename__ = "runs"
    __table_args__ = (
        UniqueConstraint("track_id", "content_hash"),
        Index("ix_runs_track_id_recorded_at", "track_id", "recorded_at"),
        Index("ix_runs_status_heartbeat_at", "status", "heartbeat_at"),
        # Never reuse the id of a deleted run: a client may still hold it.
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str | None] = mapped_column(String(200))
    track_id: Mapped[int] = mapped_column(ForeignKey("tracks.id", ondelete="RESTRICT"))
    vehicle_id: Mapped[int] = mapped_column(ForeignKey("vehicles.id", ondelete="RESTRICT"))
    source: Mapped[str] = mapped_column(String(20))  # upload | json | simulate
    original_filename: Mapped[str | None] = mapped_column(String(255))  # data only, never a path
    recorded_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    processed_at: Mapped[datetime | None] = mapped_column(UTCDateTime)

    start_chainage_m: Mapped[float | None] = mapped_column(Float)
    direction: Mapped[str] = mapped_column(String(12))
    sample_rate_hz: Mapped[float] = mapped_column(Float)
    n_samples: Mapped[int] = mapped_column(Integer)
    duration_s: Mapped[float] = mapped_column(Float)
    speed_min_mps: Mapped[float] = mapped_column(Float)
    speed_max_mps: Mapped[float] = mapped_column(Float)
    chainage_min_m: Mapped[float | None] = mapped_column(Float)
    chainage_max_m: Mapped[float | None] = mapped_column(Float)
    chainage_offset_m: Mapped[float] = mapped_column(Float, default=0.0)
    alignment_status: Mapped[str | None] = mapped_column(String(12))
    alignment_correlation: Mapped[float | None] = mapped_column(Float)
    alignment_overlap_m: Mapped[float | None] = mapped_column(Float)
    alignment_reason: Mapped[str | None] = mapped_column(Text)

    status: Mapped[str] = mapped_column(String(12), default="processing")
    stage: Mapped[str | None] = mapped_column(String(12))
    error: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    quality: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    method: Mapped[str | None] = mapped_column(String(20))
    options: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    n_soft_spots: Mapped[int | None] = mapped_column(Integer)
    vehicle_version: Mapped[int | None] = mapped_column(Integer)  # produced the results
    processing_s: Mapped[float | None] = mapped_column(Float)
    # Done, its long level (track_run_levels.long_mm) not stored yet: the worker's next step
    # (app.services.run_lifecycle.jobs.long_level).
    long_level_pending: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false())
    # Load: what the client declared, the inversion's mean wheel force, and whether
    # the run's own stiffness-loss figures are valid (rail smooth at the noise level).
    payload_kg: Mapped[float | None] = mapped_column(Float)
    static_wheel_load_n: Mapped[float | None] = mapped_column(Float)
    mean_wheel_force_n: Mapped[float | None] = mapped_column(Float)
    single_pass_valid: Mapped[bool | None] = mapped_column(Boolean)
    # GNSS placement: engine.positioning.Placement.to_dict(); None when the run was
    # placed by its start chainage.
    positioning: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    # What the run could see: engine.results.DetectionLimit.to_dict() (smallest detectable
    # stiffness loss per zone length); None until processed.
    detection_limit: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    # Retention: when the run's detail (profile, signals, log) was removed; NULL = kept.
    detail_expired_at: Mapped[datetime | None] = mapped_column(UTCDateTime)

    content_hash: Mapped[str] = mapped_column(String(64))
    idempotency_key: Mapped[str | None] = mapped_column(String(200), unique=True)

    # Work claim of the background worker (see app.services.run_lifecycle.lease).
    claimed_by: Mapped[str | None] = mapped_column(String(120))
    heartbeat_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    attempts: Mapped[int] = mapped_column(Integer, default=0)

    track: Mapped[Track] = relationship(back_populates="runs", lazy="joined")
    vehicle: Mapped[Vehicle] = relationship(lazy="joined")
    soft_spots: Mapped[list[SoftSpot]] = relationship(
        order_by="SoftSpot.start_m", passive_deletes=True, cascade="all, delete-orphan"
    )

    @property
    def offset_m(self) -> float:
        """Offset from the run's stored chainage to the track's (aligned), m; 0 until aligned."""
        return self.chainage_offset_m or 0.0

    def aligned_extent(self) -> tuple[float | None, float | None]:
        """First and last chainage of the run's profile on the track (aligned), m; None
        before the run is processed."""
        off = self.offset_m
        lo = None if self.chainage_min_m is None else self.chainage_min_m + off
        hi = None if self.chainage_max_m is None else self.chainage_max_m + off
        return lo, hi


class RunInput(Base):
    """The parsed log of a run: what the worker inverts, reprocessing and calibration read.

    ``data`` holds the canonical SI columns, float64, losslessly compressed
    (``app.services.run_lifecycle.logs.pack_log``); keeping it in the database (not on a local
    disk) lets any
    process sharing the database pick the run up. Deleted when the run fails; for processed
    runs kept under the retention policy (``app.services.storage.retention``: the newest runs of
    each
    vehicle, and never longer than the run's detail).
    """

    __tablename__ = "run_inputs"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    data: Mapped[bytes] = mapped_column(LargeBinary, deferred=True)


class RunProfileBlock(Base):
    """A run's profile over one fixed chainage block of its 0.25 m grid, compressed.

    Block ``b`` holds grid points ``b * BLOCK_POINTS ...`` (chainage = grid index x 0.25 m,
    as processed); ``first`` is the grid index of the block's first stored point and ``data``
    the columns of ``app.services.storage.profiles.PROFILE_COLUMNS`` after chainage, packed by
    ``app.services.storage.packing`` (levels to 0.0001 mm, wheel forces to 1 N, NaN = no data). A
    chainage window of a run is one range scan of the ``(run_id, block)`` key over a few
    rows. Detail: removed when the run's detail expires (``Run.detail_expired_at``).
    """

    __tablename__ = "run_profile_blocks"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    block: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    first: Mapped[int] = mapped_column(Integer)
    data: Mapped[bytes] = mapped_column(LargeBinary)


class SoftSpot(Base):
    """A detected soft spot of one run (chainage in m as processed, depth in mm)."""

    __tablename__ = "soft_spots"

    id: Mapped[int] = mapped_column(primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), index=True)
    start_m: Mapped[float] = mapped_column(Float)
    end_m: Mapped[float] = mapped_column(Float)
    peak_m: Mapped[float] = mapped_column(Float)
    depth_mm: Mapped[float] = mapped_column(Float)
    stiffness_loss_pct: Mapped[float | None] = mapped_column(Float)


class RunSignals(Base):
    """The run's raw signals against time, decimated for display (min/max envelope).

    ``packed`` holds ``time_s`` (from the first sample), ``accel_z_mps2``, ``pitch_rate_radps``
    and ``speed_mps``, equal length, at most a few thousand points, packed by
    ``app.services.views.signals.pack_signals``. Detail: removed when the run's detail expires.
    """

    __tablename__ = "run_signals"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    n_points: Mapped[int] = mapped_column(Integer)
    decimated: Mapped[bool] = mapped_column(Boolean)
    packed: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)


class ApiKey(Base):
    """A key a pipeline sends in ``X-API-Key``; only its SHA-256 is stored."""

    __tablename__ = "api_keys"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    prefix: Mapped[str] = mapped_column(String(16))
    key_hash: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    revoked_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    last_used_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    scopes: Mapped[str] = mapped_column(String(64), default="read write admin")
    """What the key may do: space-separated scopes of :mod:`app.core.scopes`."""


class TrackRunLevels(Base):
    """One aligned run's level on its track's 0.25 m grid, a chunk of grid points per row.

    ``levels`` holds ``CHUNK_POINTS`` little-endian float32 values (mm, NaN = no data) for the
    grid points ``chunk * CHUNK_POINTS ... + CHUNK_POINTS - 1`` (chainage = index x 0.25 m).
    Only runs that are the reference of their stretch or aligned to it have rows here: the
    aggregate of a chainage range is recomputed from these rows alone. ``force_n`` holds the
    wheel force under that level the same way (N; NULL for runs stored before wheel forces were
    kept). ``long_mm`` holds the run's loaded level of the long band D2 is filtered from
    (``engine.track_quality.long_level``, 3-100 m) on the same points, packed by
    ``app.services.storage.profiles.pack_long_level`` (0.001 mm; NULL for runs stored before
    it was kept, or too short for the band: D2 then comes from ``levels``, and says so).
    """

    __tablename__ = "track_run_levels"
    __table_args__ = (Index("ix_track_run_levels_track_id_chunk", "track_id", "chunk"),)

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    chunk: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    track_id: Mapped[int] = mapped_column(ForeignKey("tracks.id", ondelete="CASCADE"))
    levels: Mapped[bytes] = mapped_column(LargeBinary)
    force_n: Mapped[bytes | None] = mapped_column(LargeBinary)
    long_mm: Mapped[bytes | None] = mapped_column(LargeBinary)


class TrackProfileChunk(Base):
    """The aggregated profile of a track over one chunk of its 0.25 m grid.

    ``data`` holds, packed by ``app.services.track.aggregate.pack_chunk``, the ``CHUNK_POINTS``
    grid points ``chunk * CHUNK_POINTS ... + CHUNK_POINTS - 1`` (chainage = index x 0.25 m):
    ``level_mm`` the median over the aligned runs covering the point, ``spread_mm`` their
    robust spread (1.4826 x MAD), ``n_runs`` how many there are (0 and NaN: no run). The
    chunks are those of ``track_run_levels`` they are computed from; a chainage window is one
    range scan over a few rows. Only chunks with at least one covered point are stored.
    ``spots`` holds the soft spots of the combined passes peaking in the chunk
    (``app.services.track.aggregate.CombinedSpot`` as dicts; NULL: not computed, stored before).
    """

    __tablename__ = "track_profile_chunks"

    track_id: Mapped[int] = mapped_column(
        ForeignKey("tracks.id", ondelete="CASCADE"), primary_key=True
    )
    chunk: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    data: Mapped[bytes] = mapped_column(LargeBinary)
    spots: Mapped[list[dict[str, Any]] | None] = mapped_column(JSON, nullable=True)


class TrackLimits(Base):
    """A track's limits on defect depth (mm) and stiffness loss (%), EN 13848 style.

    NULL disables a criterion; a track without a row uses the engine's default ``Limits``.
    """

    __tablename__ = "track_limits"

    track_id: Mapped[int] = mapped_column(
        ForeignKey("tracks.id", ondelete="CASCADE"), primary_key=True
    )
    alert_depth_mm: Mapped[float | None] = mapped_column(Float)
    intervention_depth_mm: Mapped[float | None] = mapped_column(Float)
    immediate_depth_mm: Mapped[float | None] = mapped_column(Float)
    alert_loss_pct: Mapped[float | None] = mapped_column(Float)
    intervention_loss_pct: Mapped[float | None] = mapped_column(Float)
    immediate_loss_pct: Mapped[float | None] = mapped_column(Float)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)


class Survey(Base):
    """A reference survey of a track: a recording car's longitudinal level at a known wheel
    load, used as one more pass when geometry and stiffness are separated.

    ``data`` is an ``.npz`` of the survey as imported (``chainage_m``, ``level_mm``);
    ``chainage_offset_m`` aligns it to the track like a run's.
    """

    __tablename__ = "surveys"
    __table_args__ = (
        UniqueConstraint("track_id", "content_hash"),
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    track_id: Mapped[int] = mapped_column(ForeignKey("tracks.id", ondelete="CASCADE"))
    name: Mapped[str | None] = mapped_column(String(200))
    original_filename: Mapped[str | None] = mapped_column(String(255))
    recorded_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    wheel_load_n: Mapped[float] = mapped_column(Float)  # N, the recording car's wheel load
    band_min_m: Mapped[float] = mapped_column(Float)  # m, shortest wavelength of the level
    band_max_m: Mapped[float] = mapped_column(Float)  # m, longest wavelength
    n_points: Mapped[int] = mapped_column(Integer)
    chainage_min_m: Mapped[float] = mapped_column(Float)  # as imported
    chainage_max_m: Mapped[float] = mapped_column(Float)
    chainage_offset_m: Mapped[float] = mapped_column(Float, default=0.0)
    alignment_status: Mapped[str] = mapped_column(String(12))
    alignment_correlation: Mapped[float | None] = mapped_column(Float)
    alignment_reason: Mapped[str | None] = mapped_column(Text)
    content_hash: Mapped[str] = mapped_column(String(64))
    data: Mapped[bytes] = mapped_column(LargeBinary, deferred=True)


class SurveyLevels(Base):
    """A survey's aligned level on the track grid, chunked like ``TrackRunLevels`` (mm)."""

    __tablename__ = "survey_levels"
    __table_args__ = (Index("ix_survey_levels_track_id_chunk", "track_id", "chunk"),)

    survey_id: Mapped[int] = mapped_column(
        ForeignKey("surveys.id", ondelete="CASCADE"), primary_key=True
    )
    chunk: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    track_id: Mapped[int] = mapped_column(ForeignKey("tracks.id", ondelete="CASCADE"))
    levels: Mapped[bytes] = mapped_column(LargeBinary)


class TrackStiffness(Base):
    """The separated geometry and stiffness of a track over one chunk of its grid.

    ``data`` holds ``app.services.track.separation_store.STIFFNESS_ARRAYS`` one after the other,
    each
    ``CHUNK_POINTS`` little-endian float32 values (NaN = not estimated); ``meta`` lists the
    passes that reached the chunk (``contributors``: kind, id, label, mean wheel force in N,
    points). Why a stretch is not separable is derived when it is read (rows written before
    may still carry a ``message``: it is not read).
    """

    __tablename__ = "track_stiffness"

    track_id: Mapped[int] = mapped_column(
        ForeignKey("tracks.id", ondelete="CASCADE"), primary_key=True
    )
    chunk: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    data: Mapped[bytes] = mapped_column(LargeBinary)
    meta: Mapped[dict[str, Any]] = mapped_column(JSON)


class SeparatedSpotFigures:
    """What a separation says of a soft spot (aligned chainage, m; loss and its band, %; depth
    as a level dip under the separation's reference load, mm): the columns of the current
    spots and of their history."""

    id: Mapped[int] = mapped_column(primary_key=True)
    track_id: Mapped[int] = mapped_column(ForeignKey("tracks.id", ondelete="CASCADE"))
    start_m: Mapped[float] = mapped_column(Float)
    end_m: Mapped[float] = mapped_column(Float)
    peak_m: Mapped[float] = mapped_column(Float)
    loss_pct: Mapped[float] = mapped_column(Float)
    depth_mm: Mapped[float | None] = mapped_column(Float)
    loss_lo_pct: Mapped[float | None] = mapped_column(Float)
    loss_hi_pct: Mapped[float | None] = mapped_column(Float)


class TrackStiffnessSpot(SeparatedSpotFigures, Base):
    """A soft spot found by separating geometry and stiffness (aligned chainage, m; loss %)."""

    __tablename__ = "track_stiffness_spots"
    __table_args__ = (Index("ix_track_stiffness_spots_track_id_peak_m", "track_id", "peak_m"),)

    confidence: Mapped[float | None] = mapped_column(Float)
    # the passes with data over the spot: [{"kind": "run"|"survey", "id", "force_n"}]
    support: Mapped[list[dict[str, Any]] | None] = mapped_column(JSON)


class TrackSeparationHistory(SeparatedSpotFigures, Base):
    """One separation of a soft spot, kept after the next one (aligned chainage, m; loss %;
    depth mm at the separation's reference load): the register's trend and first sighting of a
    separated defect (``app.services.track.separation_history``). ``support`` is the passes behind
    the figures (as ``TrackStiffnessSpot.support``), ``base`` the passes it opened with
    (``[[kind, id], ...]``): a later separation opens the next entry when the passes it adds
    to that base span two wheel loads by themselves, and refines this one otherwise."""

    __tablename__ = "track_separation_history"
    __table_args__ = (Index("ix_track_separation_history_track_id_peak_m", "track_id", "peak_m"),)

    support: Mapped[list[dict[str, Any]]] = mapped_column(JSON)
    base: Mapped[list[list[Any]]] = mapped_column(JSON)
    separated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)


class TrackCenterline(Base):
    """A track's centerline: WGS84 vertices and the chainage of each, for placing
    runs by their GNSS fixes and drawing the line in plan."""

    __tablename__ = "track_centerlines"

    track_id: Mapped[int] = mapped_column(
        ForeignKey("tracks.id", ondelete="CASCADE"), primary_key=True
    )
    n_vertices: Mapped[int] = mapped_column(Integer)
    length_m: Mapped[float] = mapped_column(Float)
    start_chainage_m: Mapped[float] = mapped_column(Float)
    end_chainage_m: Mapped[float] = mapped_column(Float)
    source: Mapped[str] = mapped_column(String(20))  # geojson | csv
    data: Mapped[dict[str, Any]] = mapped_column(JSON, deferred=True)  # Centerline.to_dict()
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)


class TrackLineSpeed(Base):
    """A track's line speed over a chainage range (aligned chainage, m; speed km/h): picks the
    speed class of EN 13848-5's isolated-defect limits and of the quality classes."""

    __tablename__ = "track_line_speeds"
    __table_args__ = (Index("ix_track_line_speeds_track_id", "track_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    track_id: Mapped[int] = mapped_column(ForeignKey("tracks.id", ondelete="CASCADE"))
    from_m: Mapped[float] = mapped_column(Float)
    to_m: Mapped[float] = mapped_column(Float)
    speed_kmh: Mapped[float] = mapped_column(Float)


class TrackQualityLimits(Base):
    """A track's own isolated-defect limits and quality-class bounds
    (``engine.track_quality.QualityLimits.to_dict``); no row: the defaults."""

    __tablename__ = "track_quality_limits"

    track_id: Mapped[int] = mapped_column(
        ForeignKey("tracks.id", ondelete="CASCADE"), primary_key=True
    )
    data: Mapped[dict[str, Any]] = mapped_column(JSON)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)
