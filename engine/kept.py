"""Arrays kept by a key of bytes, within a memory budget: the least recently used go first.

Both the combined detection's residual rows (:class:`engine.accumulate.ResidualCache`) and the
service's unpacked chunks are results that are the same numbers whenever their input is: they
are kept by the input's content, so a changed input simply misses and is computed again.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np
from numpy.typing import NDArray

from .errors import ParameterError

__all__ = ["KeptArrays"]


class KeptArrays:
    """Arrays kept by a ``bytes`` key; thread-safe.

    Each entry is counted at the size its owner gives (the array's bytes, plus the key's where
    the key is itself large); once the entries exceed ``max_bytes`` the least recently used
    are dropped. An entry larger than the whole budget is not kept.

    Parameters
    ----------
    max_bytes : int
        Memory the kept entries may take, bytes (at least 1).
    """

    def __init__(self, max_bytes: int) -> None:
        if max_bytes < 1:
            raise ParameterError("max_bytes must be at least 1 byte", field="max_bytes")
        self.max_bytes = max_bytes
        self._kept: OrderedDict[bytes, tuple[NDArray[np.float64], int]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    @property
    def nbytes(self) -> int:
        """Memory the kept entries take, as counted, bytes."""
        return self._bytes

    def __len__(self) -> int:
        """How many entries are kept."""
        return len(self._kept)

    def get(self, key: bytes) -> NDArray[np.float64] | None:
        """The array kept under ``key`` (now the most recently used), else ``None``."""
        with self._lock:
            got = self._kept.get(key)
            if got is None:
                return None
            self._kept.move_to_end(key)
            return got[0]

    def put(self, key: bytes, array: NDArray[np.float64], size: int) -> None:
        """Keep ``array`` under ``key``, counted as ``size`` bytes (kept as given: the caller
        hands over an array nobody writes to); an entry already kept under ``key`` stays."""
        if size > self.max_bytes:
            return
        with self._lock:
            if key not in self._kept:
                self._kept[key] = (array, size)
                self._bytes += size
            while self._bytes > self.max_bytes:
                _, (_, dropped) = self._kept.popitem(last=False)
                self._bytes -= dropped
