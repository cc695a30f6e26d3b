"""What the liveness probe reports of the database: does it answer, how many runs wait."""

from __future__ import annotations

from sqlalchemy import func, select, text

from app.db.models import Run
from app.services.context import AppContext


def database_status(ctx: AppContext, *, count_processing: bool) -> tuple[bool, int | None]:
    """``(answers, runs being processed)``: whether the database answers a trivial query, and
    the number of runs in ``processing`` when ``count_processing`` (else None).

    Never raises: a database that fails in any way is reported as not answering, since the
    probe exists to say so.
    """
    try:
        with ctx.db.session() as s:
            s.execute(text("SELECT 1"))
            processing = (
                s.scalar(select(func.count()).where(Run.status == "processing"))
                if count_processing
                else None
            )
    except Exception:
        return False, None
    return True, processing
