"""Wall-time budgets: a long computation checks its budget between stages and stops.

A run whose inversion would take minutes (a huge log, parameters at the edge of their
ranges) should fail with a clear error rather than hold a processing slot that other runs
wait for. :class:`TimeBudget` is started when the computation starts; each
:meth:`TimeBudget.check` between stages raises :class:`~engine.errors.BudgetExceeded` once the
budget is spent. The check is cooperative: a stage that has started runs to its end, so the
overshoot is at most one stage.
"""

from __future__ import annotations

import time

from .errors import BudgetExceeded


class TimeBudget:
    """A wall-time budget, started on construction.

    Parameters
    ----------
    seconds : float
        The budget, s (> 0).
    what : str
        What is budgeted, for the message (e.g. ``"processing"``).
    source : str, optional
        Where the budget is set (e.g. a setting's name), for the message.
    """

    def __init__(self, seconds: float, what: str = "processing", source: str | None = None) -> None:
        if not seconds > 0:
            raise ValueError(f"a time budget must be > 0 s, got {seconds!r}")
        self.seconds = float(seconds)
        self.what = what
        self.source = source
        self._start = time.monotonic()

    @property
    def elapsed_s(self) -> float:
        """Time since the budget started, s."""
        return time.monotonic() - self._start

    def check(self, stage: str) -> None:
        """Raise :class:`~engine.errors.BudgetExceeded` when the budget is spent.

        Parameters
        ----------
        stage : str
            The stage just completed (named in the error).
        """
        elapsed = self.elapsed_s
        if elapsed > self.seconds:
            raise BudgetExceeded(
                f"{self.what} took longer than its budget of {self.seconds:g} s"
                f"{f' ({self.source})' if self.source else ''}: stopped after {stage}, at "
                f"{elapsed:.2f} s",
                budget_s=self.seconds,
                elapsed_s=elapsed,
                stage=stage,
            )
