"""The background worker: moved to :mod:`app.services.run_lifecycle` (the queue in
:mod:`~app.services.run_lifecycle.queue`, its jobs in :mod:`~app.services.run_lifecycle.jobs`).

The names stay importable from here for the modules that import them from this path.
"""

from __future__ import annotations

from .run_lifecycle.jobs import HANDOVER_GRACE_S, SEPARATION_RETRY_S
from .run_lifecycle.queue import Worker

__all__ = ["HANDOVER_GRACE_S", "SEPARATION_RETRY_S", "Worker"]
