"""Writing canonical CSV."""

from __future__ import annotations

import gzip
import os
from typing import IO, TextIO

import numpy as np
from numpy.typing import NDArray

from ..errors import ParameterError
from ..runlog import COLUMNS, RunLog

_WRITE_CHUNK = 100_000


def write_run_csv(
    log: RunLog, dest: str | os.PathLike[str] | TextIO, digits: int | None = None
) -> None:
    """Write a run log as canonical CSV.

    Columns ``time_s,accel_z_mps2,pitch_rate_radps`` then ``speed_mps``, ``chainage_m`` and
    ``wheel_load_n`` when the log has them; SI units (s, m/s², rad/s, m/s, m, N), gravity
    removed.

    Parameters
    ----------
    log : RunLog
        The run to write.
    dest : str, os.PathLike or text file object
        Where to write. A path ending in ``.gz`` is written gzip-compressed.
    digits : int, optional
        Significant digits per number (1 to 17). Default: the shortest text that reads back
        to exactly the same float (Python's ``repr``), so a round trip is lossless.

    Raises
    ------
    ParameterError
        ``digits`` is out of range.
    """
    if digits is not None and (not isinstance(digits, int) or not 1 <= digits <= 17):
        raise ParameterError(f"digits must be an integer from 1 to 17, got {digits!r}")
    names = [name for name in COLUMNS if getattr(log, name) is not None]
    cols = [getattr(log, name) for name in names]
    one = "%r" if digits is None else f"%.{digits}g"
    fmt = ",".join([one] * len(cols))
    if isinstance(dest, str | os.PathLike):
        path = os.fspath(dest)
        opener = gzip.open if path.endswith(".gz") else open
        with opener(path, "wt", encoding="utf-8", newline="\n") as fh:
            _write_rows(fh, names, cols, fmt)
    else:
        _write_rows(dest, names, cols, fmt)


def _write_rows(fh: IO[str], names: list[str], cols: list[NDArray[np.float64]], fmt: str) -> None:
    fh.write(",".join(names) + "\n")
    n = cols[0].shape[0]
    for i in range(0, n, _WRITE_CHUNK):
        # tolist() gives Python floats, whose %r is the shortest round-trip text
        block = np.column_stack([c[i : i + _WRITE_CHUNK] for c in cols]).tolist()
        fh.write("\n".join([fmt % tuple(r) for r in block]))
        fh.write("\n")
