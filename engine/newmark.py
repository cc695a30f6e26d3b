"""Newmark-beta time-integration constants shared by the forward model and the inverse."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import ParameterError


@dataclass(frozen=True)
class Newmark:
    """Newmark-beta parameters for a time step.

    Parameters
    ----------
    dt : float
        Time step, s.
    gamma, beta : float
        Newmark parameters; the default (0.5, 0.25) is the average-acceleration rule,
        unconditionally stable and non-dissipative.
    """

    dt: float
    gamma: float = 0.5
    beta: float = 0.25

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ParameterError(f"time step must be a positive number of seconds, got {self.dt}")
        if not (math.isfinite(self.gamma) and self.gamma > 0):
            raise ParameterError(f"Newmark gamma must be > 0, got {self.gamma}")
        if not (math.isfinite(self.beta) and self.beta > 0):
            raise ParameterError(f"Newmark beta must be > 0, got {self.beta}")

    @property
    def c_disp(self) -> float:
        """Predictor weight of the old acceleration in the displacement, ``(0.5 - beta) dt²``."""
        return (0.5 - self.beta) * self.dt**2

    @property
    def c_vel(self) -> float:
        """Predictor weight of the old acceleration in the velocity, ``(1 - gamma) dt``."""
        return (1.0 - self.gamma) * self.dt

    @property
    def bdt2(self) -> float:
        """Weight of the new acceleration in the displacement, ``beta dt²``."""
        return self.beta * self.dt**2

    @property
    def gdt(self) -> float:
        """Weight of the new acceleration in the velocity, ``gamma dt``."""
        return self.gamma * self.dt
