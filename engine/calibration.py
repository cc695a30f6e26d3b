"""Vehicle calibration from its own runs: fit what the logs identify.

The front and rear axle ride over the same rail, the rear ``d1 + d2`` later. Inverted with the
right vehicle, both axles' recovered levels agree on chainage up to the sensor noise; with a
wrong pitch inertia or suspension the inverse leaves ghost dips that differ between the axles.
The objective is that disagreement, in the product's wavelength band, normalised by the level's
energy, summed over many runs:

``J(θ) = Σ_k ‖y_front,k − y_rear,k‖² / Σ_k ½(‖y_front,k‖² + ‖y_rear,k‖²)``

over segments ``k`` of the runs, both levels on the front axle's chainage samples. The half-car
is linear: the inverse is ``Y(ω) = G(ω; θ) [A(ω); Q(ω)]``, so the signals are decimated to the
band, cut into segments and Fourier-transformed once; each evaluation only rebuilds the 2x2
operator ``G`` per frequency bin and transforms back (:func:`engine.spectral.solve_bins`).

What the data identify: ``H(ω)`` is unchanged when every mass, stiffness and damping is scaled
by the same factor, so only ratios are observable. The body mass is held (registered value or
a given load figure) and the pitch inertia, the suspension stiffnesses and the sensor position
are fitted against it; damping and contact stiffness barely change the disagreement in the band
and are held too.

The objective's machinery (segments, spectra, evaluation) is :mod:`engine.axle_disagreement`;
this module holds the fit and its public objects (what is fittable, the configuration, the
result with its uncertainties), whose numpydoc is half of its length.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from . import axle_disagreement as disagreement
from .axle_disagreement import Evaluation
from .bogie import BogieParams
from .chainage import PRODUCT_BAND_M
from .errors import ParameterError
from .runlog import RunLog
from .vehicle import VehicleParams
from .vehicle_kinds import Vehicle


def _of_kind(
    vehicle_kind: str, half_car: tuple[str, ...], bogie: tuple[str, ...]
) -> tuple[str, ...]:
    """Parameter names of a vehicle of ``vehicle_kind``: the half car's or the bogie vehicle's."""
    return {VehicleParams.kind: half_car, BogieParams.kind: bogie}[vehicle_kind]


@dataclass(frozen=True)
class Fittable:
    """How one fitted quantity moves the vehicle: ``apply(params, theta) -> changes``.

    ``theta`` is dimensionless (log of a factor) for ``scale`` quantities, m for positions.
    ``targets`` are the half car's parameters it moves; ``bogie`` those of a bogie vehicle
    (empty: not fittable there). :meth:`targets_of` picks by the vehicle's kind.
    """

    name: str
    description: str
    unit: str
    kind: str  # "scale" (theta = log factor) | "offset" (theta in the parameter's unit)
    targets: tuple[str, ...]
    bogie: tuple[str, ...] = ()

    def targets_of(self, vehicle_kind: str) -> tuple[str, ...]:
        """The parameters this quantity moves on a vehicle of ``vehicle_kind``."""
        return _of_kind(vehicle_kind, self.targets, self.bogie)

    def apply(self, base: Vehicle, theta: float) -> dict[str, float]:
        """Parameter values of ``base`` moved by ``theta``."""
        targets = self.targets_of(base.kind)
        if self.kind == "scale":
            f = math.exp(theta)
            return {t: getattr(base, t) * f for t in targets}
        return {t: getattr(base, t) + theta for t in targets}


FITTABLE: dict[str, Fittable] = {
    f.name: f
    for f in (
        Fittable("Is", "body pitch inertia", "kg m²", "scale", ("Is",),
                 ("body_pitch_inertia_kgm2",)),
        Fittable("ks", "both suspension stiffnesses (one factor; a bogie vehicle's secondary)",
                 "N/m", "scale", ("ks1", "ks2"), ("secondary_k_n_per_m",)),
        Fittable("ks1", "front suspension stiffness", "N/m", "scale", ("ks1",)),
        Fittable("ks2", "rear suspension stiffness", "N/m", "scale", ("ks2",)),
        Fittable("kp", "primary suspension stiffness (bogie vehicles)", "N/m", "scale", (),
                 ("primary_k_n_per_m",)),
        Fittable("cs", "both suspension dampings (one factor; a bogie vehicle's secondary)",
                 "N s/m", "scale", ("cs1", "cs2"), ("secondary_c_ns_per_m",)),
        Fittable("sensor_x_m", "accelerometer position ahead of the CG", "m", "offset",
                 ("sensor_x_m",), ("sensor_x_m",)),
    )
}  # fmt: skip
"""Quantities calibration can fit, by name (registry: add one here to make it fittable)."""

DEFAULT_FIT: tuple[str, ...] = ("Is", "ks1", "ks2")
"""What is fitted on a half car unless told otherwise: pitch inertia and both suspension
stiffnesses."""

DEFAULT_FIT_BY_KIND: dict[str, tuple[str, ...]] = {
    VehicleParams.kind: DEFAULT_FIT,
    BogieParams.kind: ("Is", "ks"),
}
"""What is fitted unless told otherwise, per vehicle kind. A bogie vehicle has one secondary
for both bogies (its datasheet's): the body's pitch inertia and that stiffness; its primary
(``kp``) is in series with it, identifiable only where it is the softer stage (a freight
wagon: then ask for ``kp``, else its error is fitted into the secondary). Fitting ``kp`` by
default on such a vehicle did not improve the separation (docs/accuracy.md, "The wagon's
primary in the default fit?"), so it is not the default."""


def held_vehicle(vehicle: Vehicle, load_kg: float | None) -> Vehicle:
    """The vehicle calibration starts from: the registered one, or with the per-rail body
    mass ``load_kg`` (kg) of a load figure. A half car's ``ms`` is replaced as given; a bogie
    vehicle's body is that mass, its pitch inertia scaled with it
    (:meth:`engine.bogie.BogieParams.with_body_mass`)."""
    if load_kg is None:
        return vehicle
    hold: dict[str, Callable[[Any, float], Vehicle]] = {
        VehicleParams.kind: lambda v, m: v.replace(ms=m),
        BogieParams.kind: lambda v, m: v.with_body_mass(m),
    }
    return hold[vehicle.kind](vehicle, load_kg)


SYSTEMATIC_SD: dict[str, float] = {"scale": 0.02, "offset": 0.05}
"""Systematic part of the uncertainty (relative for scales, m for positions), added to the
statistical one: on runs of a vehicle that matches its registration the fit still moves the
parameters by up to ~2-4 % (the front and rear loaded levels differ a little: different axle
loads, dynamic wheel force), far more than the segment scatter says."""

FIT_BOUND: dict[str, float] = {"scale": 1.2, "offset": 10.0}
"""The fit's range per kind of quantity: ``|theta|`` at most this (a factor ×0.30-×3.32 for
scale quantities, ±10 m for positions)."""

AT_BOUND_TOL = 0.1
"""A fitted value within this fraction of its quantity's step scale (0.1 in log factor,
0.5 m: 1 % or 0.05 m) of :data:`FIT_BOUND` is "at the bound" and never applied."""


@dataclass(frozen=True)
class Unidentifiable:
    """A quantity the logs cannot fix, held at its registered value: ``reason`` says why;
    ``targets`` are the half car's parameters it is, ``bogie`` those of a bogie vehicle."""

    reason: str
    targets: tuple[str, ...]
    bogie: tuple[str, ...]

    def name_of(self, vehicle_kind: str) -> str:
        """How a result of a ``vehicle_kind`` vehicle names it (its parameters, ``/``-joined)."""
        return "/".join(_of_kind(vehicle_kind, self.targets, self.bogie))


NOT_IDENTIFIABLE: tuple[Unidentifiable, ...] = (
    Unidentifiable(
        "absolute body mass: the response depends only on ratios of masses, stiffnesses and "
        "dampings (scaling all of them changes nothing); held at the registered value or the "
        "given load figure",
        ("ms",), ("body_mass_kg",),
    ),
    Unidentifiable(
        "contact stiffness: barely changes the response in the 3-40 m band; held",
        ("kt1", "kt2"), ("contact_k_n_per_m",),
    ),
    Unidentifiable(
        "axle masses: barely change the response in the band; held",
        ("mu1", "mu2"), ("wheelset_mass_kg",),
    ),
)  # fmt: skip
"""Quantities the logs cannot fix, and why (reported in every result, named by the vehicle
kind's own parameters: :func:`not_identifiable`)."""


def not_identifiable(vehicle_kind: str) -> dict[str, str]:
    """What a calibration of a ``vehicle_kind`` vehicle cannot fix, by its parameter names."""
    return {q.name_of(vehicle_kind): q.reason for q in NOT_IDENTIFIABLE}


@dataclass(frozen=True)
class CalibrationRun:
    """One run to calibrate from.

    Attributes
    ----------
    log : RunLog
        The log, canonical SI units.
    start_chainage_m : float, optional
        Body-centre chainage at the first sample, m (needed without a chainage column).
    direction : {"increasing", "decreasing"}
        Direction of travel.
    label : str
        How the result names the run (e.g. its id).
    body_mass_kg : float, optional
        The body mass the run was driven with, kg, when its load was declared (a payload, a
        measured static wheel load: what the run was inverted with). The run is then compared
        at that mass, the fitted quantities applied as to every run
        (:meth:`engine.vehicle.VehicleParams.with_body_mass`); None: the held body mass.
    """

    log: RunLog
    start_chainage_m: float | None = None
    direction: str = "increasing"
    label: str = ""
    body_mass_kg: float | None = None


@dataclass(frozen=True)
class CalibrationConfig:
    """Settings of :func:`calibrate`.

    Parameters
    ----------
    fit : sequence of str, optional
        Quantities to fit, names of :data:`FITTABLE` (default: the vehicle kind's,
        :data:`DEFAULT_FIT_BY_KIND`).
    load_kg : float, optional
        Known body mass (load/tare figure), kg: replaces the registered ``ms`` before fitting.
    lambda_min_m, lambda_max_m : float
        Wavelength band compared, m (the product's band by default).
    segment_s : float
        Length of the segments runs are cut into, s.
    max_seconds_per_run : float, optional
        Use at most this much of each run (evenly spread segments), s; None: all of it.
    significance : float
        A fitted value is a significant change when it differs from the registered one by
        more than this many standard uncertainties and by more than ``min_change`` (and the
        objective improves by ``min_improvement``).
    min_change : float
        Smallest change that matters: relative for scale quantities; ten times it in m for
        the sensor position (0.05: 5 %, 0.5 m).
    min_improvement : float
        Relative objective decrease below which a calibration is "no significant change".
    max_relative_sd : float
        A scale quantity whose relative uncertainty exceeds this is reported as not identified.
    """

    fit: tuple[str, ...] | None = None
    load_kg: float | None = None
    lambda_min_m: float = PRODUCT_BAND_M[0]
    lambda_max_m: float = PRODUCT_BAND_M[1]
    segment_s: float = 40.0
    max_seconds_per_run: float | None = None
    significance: float = 3.0
    min_change: float = 0.05
    min_improvement: float = 0.05
    max_relative_sd: float = 0.15

    def __post_init__(self) -> None:
        if self.fit is None:
            return self._check_rest()
        fit = tuple(self.fit)
        object.__setattr__(self, "fit", fit)
        if not fit:
            raise ParameterError("calibration needs at least one quantity to fit")
        unknown = [f for f in fit if f not in FITTABLE]
        if unknown:
            raise ParameterError(
                f"cannot fit {unknown}; fittable quantities are {sorted(FITTABLE)}"
            )
        if len(set(fit)) != len(fit):
            raise ParameterError(f"quantities to fit are repeated: {list(fit)}")
        for kind in (VehicleParams.kind, BogieParams.kind):
            targets = [t for f in fit for t in FITTABLE[f].targets_of(kind)]
            if len(set(targets)) != len(targets):
                raise ParameterError(
                    f"fitted quantities overlap (e.g. 'ks' with 'ks1'): {list(fit)}"
                )
        self._check_rest()

    def fit_for(self, vehicle_kind: str) -> tuple[str, ...]:
        """The quantities fitted on a vehicle of ``vehicle_kind``.

        Raises
        ------
        ParameterError
            ``field="fit"``: a quantity that kind does not have (e.g. ``ks1`` on a bogie
            vehicle, whose bogies share one secondary).
        """
        if self.fit is None:
            return DEFAULT_FIT_BY_KIND[vehicle_kind]
        missing = [f for f in self.fit if not FITTABLE[f].targets_of(vehicle_kind)]
        if missing:
            have = sorted(n for n, f in FITTABLE.items() if f.targets_of(vehicle_kind))
            raise ParameterError(
                f"cannot fit {missing} on a {vehicle_kind} vehicle; its fittable quantities "
                f"are {have}",
                field="fit",
            )
        return self.fit

    def _check_rest(self) -> None:
        if self.load_kg is not None and not (math.isfinite(self.load_kg) and self.load_kg > 0):
            raise ParameterError(f"load_kg must be a positive body mass in kg, got {self.load_kg}")
        if not (0 < self.lambda_min_m < self.lambda_max_m):
            raise ParameterError("wavelength band must satisfy 0 < lambda_min_m < lambda_max_m")
        if not (5.0 <= self.segment_s <= 600.0):
            raise ParameterError(f"segment_s must be 5..600 s, got {self.segment_s}")
        if self.max_seconds_per_run is not None and not self.max_seconds_per_run >= self.segment_s:
            raise ParameterError("max_seconds_per_run must be at least one segment_s")


@dataclass(frozen=True)
class FittedParameter:
    """One fitted quantity.

    Attributes
    ----------
    name, description, unit : str
        Which quantity (a name of :data:`FITTABLE`).
    before, after : dict of str to float
        Registered and fitted values of the vehicle parameters it moves (SI).
    change : float
        Relative change (scale quantities, fraction) or shift (positions, m).
    sd : float
        Standard uncertainty of ``change`` (same unit): the segment-to-segment scatter
        combined with the systematic floor :data:`SYSTEMATIC_SD`.
    identified : bool
        False when the uncertainty is too large for the data to fix it.
    significant : bool
        ``|change| > significance * sd`` (and identified).
    at_bound : bool
        The fitted value sits at the fit's range (:data:`FIT_BOUND`).
    applied : bool
        In the result's vehicle: significant, not at the bound, and the result significant.
        Otherwise the registered value is kept (``after`` is the fit's value all the same).
    """

    name: str
    description: str
    unit: str
    before: dict[str, float]
    after: dict[str, float]
    change: float
    sd: float
    identified: bool
    significant: bool
    at_bound: bool = False
    applied: bool = False


@dataclass(frozen=True)
class RunFit:
    """How well one run's axles agree, before and after (relative disagreement, fraction)."""

    label: str
    seconds_used: float
    objective_before: float
    objective_after: float


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate` found.

    Attributes
    ----------
    params : VehicleParams or BogieParams
        The calibrated vehicle (the registered one where nothing was fitted).
    registered : VehicleParams or BogieParams
        The vehicle calibration started from (after a given load figure, if any).
    fitted : list of FittedParameter
        One per fitted quantity.
    objective_before, objective_after : float
        Relative front/rear disagreement ``sqrt(J)`` with the registered and the calibrated
        vehicle (fraction of the level's RMS).
    disagreement_before_mm, disagreement_after_mm : float
        RMS front/rear difference, mm.
    significant : bool
        The calibration changes something beyond its uncertainty and improves the objective.
    message : str
        Plain-words summary.
    runs : list of RunFit
        The runs used.
    skipped : list of (label, reason)
        Runs that could not be used.
    not_identified : dict of str to str
        Parameters the data could not fix, and why.
    n_evaluations : int
        Objective evaluations.
    seconds : float
        Wall time, s.
    scans : dict of str to (values, objective)
        The objective along each fitted quantity through the optimum (for plots).
    """

    params: Vehicle
    registered: Vehicle
    fitted: list[FittedParameter]
    objective_before: float
    objective_after: float
    disagreement_before_mm: float
    disagreement_after_mm: float
    significant: bool
    message: str
    runs: list[RunFit]
    skipped: list[tuple[str, str]]
    not_identified: dict[str, str]
    n_evaluations: int
    seconds: float
    scans: dict[str, tuple[list[float], list[float]]] = field(default_factory=dict)

    def estimates(self) -> dict[str, tuple[float, float]]:
        """Fitted vehicle parameters with absolute standard uncertainties, SI: name -> (value,
        sd) (what the suspension-health history records); a value at the fit's bound is no
        estimate and is left out."""
        out: dict[str, tuple[float, float]] = {}
        for f in self.fitted:
            if f.at_bound:
                continue
            for name, value in f.after.items():
                sd = f.sd * value if FITTABLE[f.name].kind == "scale" else f.sd
                out[name] = (value, abs(sd))
        return out

    def to_dict(self) -> dict[str, object]:
        """JSON-safe plain dict (SI units)."""
        return {
            "params": self.params.to_dict(),
            "registered": self.registered.to_dict(),
            "fitted": [vars(f) | {} for f in self.fitted],
            "objective_before": self.objective_before,
            "objective_after": self.objective_after,
            "disagreement_before_mm": self.disagreement_before_mm,
            "disagreement_after_mm": self.disagreement_after_mm,
            "significant": self.significant,
            "message": self.message,
            "runs": [vars(r) | {} for r in self.runs],
            "skipped": [{"label": a, "reason": b} for a, b in self.skipped],
            "not_identified": dict(self.not_identified),
            "n_evaluations": self.n_evaluations,
            "seconds": self.seconds,
            "scans": {k: {"change": v[0], "objective": v[1]} for k, v in self.scans.items()},
        }


def _vehicle_at(base: Vehicle, fit: tuple[str, ...], theta: NDArray[np.float64]) -> Vehicle:
    changes: dict[str, float] = {}
    for name, t in zip(fit, theta, strict=True):
        changes |= FITTABLE[name].apply(base, float(t))
    return base.replace(**changes)


def calibrate(
    runs: Sequence[CalibrationRun],
    vehicle: Vehicle,
    config: CalibrationConfig | None = None,
    *,
    progress: Callable[[int], None] | None = None,
) -> CalibrationResult:
    """Fit the vehicle's identifiable parameters to its runs (front/rear axle agreement).

    Parameters
    ----------
    runs : sequence of CalibrationRun
        The vehicle's runs (many together: the fit is joint).
    vehicle : VehicleParams or BogieParams
        The registered vehicle (starting point; held parameters keep its values).
    config : CalibrationConfig, optional
        What to fit, band, segmenting, significance thresholds.
    progress : callable, optional
        Called with the number of objective evaluations so far (e.g. a heartbeat).

    Returns
    -------
    CalibrationResult

    Raises
    ------
    ParameterError
        If no run can be used, or the configuration is invalid.
    """
    t0 = time.perf_counter()
    cfg = config or CalibrationConfig()
    base = held_vehicle(vehicle, cfg.load_kg)
    fit = cfg.fit_for(vehicle.kind)
    if not runs:
        raise ParameterError("calibration needs at least one run")
    groups, skipped, used = disagreement.prepare(runs, base, cfg)
    if not groups:
        reasons = "; ".join(f"{a}: {b}" for a, b in skipped)
        raise ParameterError(f"no run can be used for calibration ({reasons})")
    k = len(fit)
    n_eval = 0
    cache: dict[bytes, Evaluation] = {}

    def evaluate(theta: NDArray[np.float64]) -> Evaluation:
        nonlocal n_eval
        key = np.asarray(theta, float).tobytes()
        if key not in cache:
            try:
                cache[key] = disagreement.evaluate(groups, _vehicle_at(base, fit, theta))
            except ParameterError:  # outside the physical range (at any run's mass): a wall
                ev0 = cache[np.zeros(k).tobytes()]
                cache[key] = Evaluation([d * 0 + 1e3 for d in ev0.diff], ev0.energy, ev0.run)
            n_eval += 1
            if progress is not None:
                progress(n_eval)
        return cache[key]

    def residual(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        ev = evaluate(theta)
        return np.concatenate(ev.diff) / math.sqrt(float(ev.energy.sum()))

    theta0 = np.zeros(k)
    r0 = residual(theta0)
    scale = np.array([0.1 if FITTABLE[f].kind == "scale" else 0.5 for f in fit])
    upper = np.array([FIT_BOUND[FITTABLE[f].kind] for f in fit])
    lower = -upper
    sol = least_squares(
        residual, theta0, x_scale=scale, bounds=(lower, upper), diff_step=1e-3,
        xtol=1e-4, ftol=1e-6, max_nfev=60,
    )  # fmt: skip
    theta = sol.x
    r1 = residual(theta)
    ev0, ev1 = evaluate(theta0), evaluate(theta)
    sd = _uncertainty(sol.jac, ev1)
    J0 = float(np.sum(r0**2))
    J1 = float(np.sum(r1**2))
    if J1 > J0:  # never worse than the registered vehicle
        theta, J1, ev1 = theta0, J0, ev0
    not_identified = not_identifiable(base.kind)
    rows: list[dict[str, Any]] = []
    for i, name in enumerate(fit):
        fdef = FITTABLE[name]
        change = math.expm1(theta[i]) if fdef.kind == "scale" else float(theta[i])
        scale_kind = fdef.kind == "scale"
        s_stat = float(sd[i]) * (math.exp(theta[i]) if scale_kind else 1.0)
        s_i = math.hypot(s_stat, SYSTEMATIC_SD[fdef.kind])
        limit = cfg.max_relative_sd if scale_kind else 0.5
        identified = bool(np.isfinite(s_i) and s_i <= limit)
        if not identified:
            not_identified[name] = (
                f"{fdef.description}: uncertainty ±{s_i:.3g}"
                f"{'' if fdef.kind == 'scale' else ' m'} is too large for these runs"
            )
        floor = cfg.min_change * (1.0 if scale_kind else 10.0)
        significant = identified and abs(change) > max(cfg.significance * s_i, floor)
        at_bound = bool(abs(theta[i]) >= upper[i] - AT_BOUND_TOL * scale[i])
        rows.append(
            dict(
                name=name, description=fdef.description, unit=fdef.unit, change=float(change),
                sd=s_i, identified=identified, significant=significant, at_bound=at_bound,
            )
        )  # fmt: skip
    # Only parameters that are significant and inside the fit's range are applied; the
    # others keep their registered values (a value at the bound is the fit running away
    # with an error it cannot place, not an estimate).
    keep = np.array([r["significant"] and not r["at_bound"] for r in rows], dtype=bool)
    theta_applied = np.where(keep, theta, 0.0)
    ev_applied = evaluate(theta_applied)
    J_applied = float(np.sum(residual(theta_applied) ** 2))
    improvement = 1.0 - J_applied / J0 if J0 > 0 else 0.0
    significant = bool(keep.any()) and improvement >= cfg.min_improvement
    params = _vehicle_at(base, fit, theta)
    fitted = [
        FittedParameter(
            **r,
            before={t: float(getattr(base, t)) for t in FITTABLE[r["name"]].targets_of(base.kind)},
            after={t: float(getattr(params, t)) for t in FITTABLE[r["name"]].targets_of(base.kind)},
            applied=significant and bool(k),
        )
        for r, k in zip(rows, keep, strict=True)
    ]
    if significant:  # what the result's vehicle gives: the applied parameters alone
        J1, ev1 = J_applied, ev_applied
    per_run = []
    for r_i, (label, secs) in enumerate(used):
        per_run.append(
            RunFit(
                label,
                secs,
                disagreement.run_objective(ev0, r_i),
                disagreement.run_objective(ev1, r_i),
            )
        )
    mm0 = disagreement.rms_mm(ev0)
    mm1 = disagreement.rms_mm(ev1)
    if significant:
        changed = ", ".join(
            f"{f.name} {f.change:+.1%} ± {f.sd:.1%}"
            if FITTABLE[f.name].kind == "scale"
            else f"{f.name} {f.change:+.2f} ± {f.sd:.2f} m"
            for f in fitted
            if f.applied
        )
        kept = "".join(
            f"; {f.name} kept as registered ("
            + ("at the fit's bound" if f.at_bound else "not significant")
            + ")"
            for f in fitted
            if not f.applied
        )
        message = (
            f"calibrated: {changed}{kept}; front/rear disagreement {math.sqrt(J0):.1%} -> "
            f"{math.sqrt(J1):.1%} of the level over {len(used)} run(s)"
        )
    else:
        message = (
            "no significant change: the registered parameters fit these runs "
            f"(disagreement {math.sqrt(J0):.1%} -> {math.sqrt(J1):.1%}, every fitted change "
            "within its uncertainty or too small to matter)"
        )
    # params reported only when significant: otherwise the registered vehicle stands
    result_params = _vehicle_at(base, fit, theta_applied) if significant else base
    scans = _scans(evaluate, theta, sd, fit)
    return CalibrationResult(
        params=result_params,
        registered=base,
        fitted=fitted,
        objective_before=math.sqrt(J0),
        objective_after=math.sqrt(J1),
        disagreement_before_mm=mm0,
        disagreement_after_mm=mm1,
        significant=significant,
        message=message,
        runs=per_run,
        skipped=skipped,
        not_identified=not_identified,
        n_evaluations=n_eval,
        seconds=time.perf_counter() - t0,
        scans=scans,
    )


def _uncertainty(jac: NDArray[np.float64], ev: Evaluation) -> NDArray[np.float64]:
    """Standard uncertainty of the fitted ``theta`` from the segment-to-segment scatter.

    Each segment's own Gauss-Newton optimum ``theta_k = theta - H_k⁻¹ g_k`` (its rows of the
    final Jacobian) is an independent estimate; the joint fit is their (curvature-weighted)
    mean, so its uncertainty is the weighted scatter over ``sqrt(n)``. With fewer than three
    segments: the curvature of the whole objective with the residual variance.
    """
    k = jac.shape[1]
    sizes = [d.size for d in ev.diff]
    bounds = np.cumsum([0, *sizes])
    r = np.concatenate(ev.diff) / math.sqrt(float(ev.energy.sum()))
    Htot = jac.T @ jac
    if len(sizes) < 3:
        dof = max(1, r.size - k)
        cov = np.linalg.pinv(Htot) * float(r @ r) / dof
        return np.sqrt(np.clip(np.diag(cov), 0, None))
    est = []
    weights = []
    for i in range(len(sizes)):
        Ji = jac[bounds[i] : bounds[i + 1]]
        ri = r[bounds[i] : bounds[i + 1]]
        Hi = Ji.T @ Ji
        est.append(-np.linalg.pinv(Hi) @ (Ji.T @ ri))
        weights.append(np.diag(Hi))
    E = np.array(est)
    W = np.array(weights)
    W = W / W.sum(axis=0, keepdims=True)
    mean = np.sum(W * E, axis=0)
    var = np.sum(W * (E - mean) ** 2, axis=0)
    n_eff = 1.0 / np.sum(W**2, axis=0)
    return np.sqrt(var / np.maximum(n_eff - 1.0, 1.0))


def _scans(
    evaluate: Callable[[NDArray[np.float64]], Evaluation],
    theta: NDArray[np.float64],
    sd: NDArray[np.float64],
    fit: tuple[str, ...],
) -> dict[str, tuple[list[float], list[float]]]:
    """The objective along each fitted quantity through the optimum (5 points, ±30 % / ±2 m)."""
    out: dict[str, tuple[list[float], list[float]]] = {}
    for i, name in enumerate(fit):
        scale = FITTABLE[name].kind == "scale"
        span = 0.3 if scale else 2.0
        xs, js = [], []
        for step in np.linspace(-span, span, 5):
            th = theta.copy()
            th[i] = theta[i] + (math.log1p(step) if scale else step)
            ev = evaluate(th)
            d = sum(float(np.sum(x**2)) for x in ev.diff)
            e = float(ev.energy.sum())
            xs.append(float(math.expm1(th[i]) if scale else th[i]))
            js.append(math.sqrt(d / e))
        out[name] = (xs, js)
    return out
