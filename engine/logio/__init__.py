"""Reading run logs as loggers write them, and writing canonical ones.

A logger's CSV is turned into a :class:`~engine.runlog.RunLog` (SI units, gravity removed) by
:func:`read_run_csv`. Column names and units are recognised from the header (``time_s``,
``timestamp``, ``az_g``, ``gyro_y_dps``, ``speed_kmh``, ``chainage_m``, ...) unless
:class:`CsvOptions` names them; everything else about the file is checked up front, and every
problem is a :class:`~engine.errors.LogFormatError` naming the column, the 1-based line of the
file (the header is line 1 when nothing precedes it) and the unit expected.

Accepted input: bytes, a path or a binary file object; gzip-compressed or plain; UTF-8 (with or
without BOM), UTF-16 with BOM, or Windows-1252 text; ``\\n``, ``\\r\\n`` or ``\\r`` line ends;
``,``, ``;``, tab or whitespace delimiters; ``#`` comment lines. Decimal commas are refused.

The numbers are read by pyarrow's multi-threaded CSV parser straight from the bytes (UTF-8,
``,``/``;``/tab, no comments: the common case) and otherwise, or when it refuses the file, by
the reference reader: numpy's C tokenizer over the decoded text, and only for a file that
rejects, line by line, which either reads it (text in columns that are not used, trailing
delimiters) or finds the exact line that is wrong. Both give the same numbers bit for bit.

The package, one module per step (each imports only from the ones above it):

- :mod:`.roles`: what each column means, the names and units it goes by;
- :mod:`.options`: :class:`CsvOptions`, the user's choices;
- :mod:`.source`: bytes, gzip and text encoding;
- :mod:`.header`: header line, delimiter, fields;
- :mod:`.columns`: which header name plays which role;
- :mod:`.threaded`: the numbers by pyarrow, where it reads them exactly as the reference;
- :mod:`.table`: the numbers (threaded, fast and careful paths);
- :mod:`.units`: the one unit resolution shared by parsing and preview;
- :mod:`.parse`: :func:`parse_run_csv`, :func:`read_run_csv`;
- :mod:`.preview`: :func:`preview_csv`;
- :mod:`.write`: :func:`write_run_csv`.
"""

from ..plausibility import (
    ACCEL_LIMIT_MPS2,
    GAP_FACTOR,
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    PITCH_RATE_LIMIT_RADPS,
    SPEED_MAX_MPS,
    SPEED_MIN_MPS,
    STEP_TOLERANCE,
)
from .options import CsvOptions
from .parse import MIN_SAMPLES, ParsedRun, parse_run_csv, read_run_csv
from .preview import PREVIEW_BYTES, CsvPreview, preview_csv
from .roles import (
    G_UNIT_MPS2,
    GRAVITY_MODES,
    OPTION_UNITS,
    OPTIONAL_ROLES,
    ROLE_LABELS,
    ROLES,
    UNIT_LABELS,
)
from .source import MAX_DECOMPRESSED_BYTES, Source
from .units import EPOCH_MS_THRESHOLD, EPOCH_THRESHOLD_S, GRAVITY_TOLERANCE_MPS2
from .write import write_run_csv

__all__ = [
    "ACCEL_LIMIT_MPS2", "EPOCH_MS_THRESHOLD", "EPOCH_THRESHOLD_S", "GAP_FACTOR",
    "GRAVITY_MODES", "GRAVITY_TOLERANCE_MPS2", "G_UNIT_MPS2", "MAX_DECOMPRESSED_BYTES",
    "MAX_RATE_HZ", "MIN_RATE_HZ", "MIN_SAMPLES", "OPTIONAL_ROLES", "OPTION_UNITS",
    "PITCH_RATE_LIMIT_RADPS",
    "PREVIEW_BYTES", "ROLES", "ROLE_LABELS", "SPEED_MAX_MPS", "SPEED_MIN_MPS", "STEP_TOLERANCE",
    "UNIT_LABELS", "CsvOptions", "CsvPreview", "ParsedRun", "Source", "parse_run_csv",
    "preview_csv", "read_run_csv", "write_run_csv",
]  # fmt: skip
