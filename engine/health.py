"""Suspension health: a vehicle's calibrated parameters over time, and changes beyond noise.

Every calibration estimates the fitted parameters (with uncertainties) from the runs of a
period. A spring or damper that fails shows up as an estimate that moves away from the earlier
ones by more than both uncertainties allow: that is an alert (which parameter, from -> to,
since when). A small drift within the uncertainty is not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

from .errors import ParameterError


@dataclass(frozen=True)
class ParameterEstimate:
    """One calibrated value of one vehicle parameter.

    Attributes
    ----------
    parameter : str
        Vehicle parameter name (e.g. ``ks1``).
    value, sd : float
        Estimate and its standard uncertainty, SI units of the parameter.
    at : datetime
        When the runs it comes from were recorded (e.g. the first of them).
    label : str
        Where it comes from (e.g. the calibration id).
    """

    parameter: str
    value: float
    sd: float
    at: datetime
    label: str = ""


@dataclass(frozen=True)
class HealthAlert:
    """A parameter that changed beyond its uncertainty.

    Attributes
    ----------
    parameter : str
        Vehicle parameter name.
    before, after : float
        Reference and new estimate, SI units.
    before_sd, after_sd : float
        Their standard uncertainties.
    change : float
        Relative change ``after / before - 1`` (positions: the shift, m).
    sigmas : float
        The change in combined standard uncertainties.
    since : datetime
        When the runs of the new estimate started.
    reference_label, label : str
        Where the reference and the new estimate come from.
    """

    parameter: str
    before: float
    after: float
    before_sd: float
    after_sd: float
    change: float
    sigmas: float
    since: datetime
    reference_label: str
    label: str

    @property
    def message(self) -> str:
        """Plain-words summary."""
        return (
            f"{self.parameter} changed {self.change:+.0%} ({self.before:.4g} -> {self.after:.4g}, "
            f"{self.sigmas:.1f} standard uncertainties) since {self.since:%Y-%m-%d}"
        )


def health_alerts(
    history: Sequence[ParameterEstimate], *, sigmas: float = 3.0, min_change: float = 0.10
) -> list[HealthAlert]:
    """Changes of each parameter beyond its uncertainty, in time order.

    Parameters
    ----------
    history : sequence of ParameterEstimate
        Estimates of any parameters, in any order.
    sigmas : float
        A change must exceed this many combined standard uncertainties ...
    min_change : float
        ... and this relative change (a 10 % stiffness change is worth looking at).

    Returns
    -------
    list of HealthAlert
        The first estimate of each parameter is its reference; an estimate beyond the
        thresholds from the reference is an alert and becomes the new reference (a parameter
        that stays at its new value alerts once).
    """
    if sigmas <= 0 or min_change < 0:
        raise ParameterError("sigmas must be > 0 and min_change >= 0")
    alerts: list[HealthAlert] = []
    by_param: dict[str, list[ParameterEstimate]] = {}
    for e in history:
        if math.isfinite(e.value) and math.isfinite(e.sd):
            by_param.setdefault(e.parameter, []).append(e)
    for name, items in sorted(by_param.items()):
        items.sort(key=lambda e: e.at)
        ref = items[0]
        for e in items[1:]:
            combined = math.hypot(ref.sd, e.sd)
            diff = e.value - ref.value
            rel = diff / ref.value if ref.value != 0 else math.inf
            n_sig = abs(diff) / combined if combined > 0 else math.inf
            if n_sig > sigmas and abs(rel) > min_change:
                alerts.append(
                    HealthAlert(
                        parameter=name, before=ref.value, after=e.value, before_sd=ref.sd,
                        after_sd=e.sd, change=rel, sigmas=n_sig, since=e.at,
                        reference_label=ref.label, label=e.label,
                    )
                )  # fmt: skip
                ref = e
    alerts.sort(key=lambda a: a.since)
    return alerts
