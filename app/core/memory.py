"""Memory the service's work frees: kept while it is busy, handed back once it is idle.

An hour's log takes about a gigabyte while it is parsed, inverted and stored, most of it in
numpy arrays of 1-100 MB. Two costs pull in opposite directions:

* Pages handed back to the operating system must be faulted in again by the next run, and on
  a virtual machine whose host reclaims a guest's free pages (virtio-balloon free page
  reporting, as on the benchmark machine) each gigabyte costs ~1.8 s to touch again. glibc's
  defaults hand most of them back at once (large arrays are separate mappings, unmapped when
  freed). Kept in the process instead, the next hour-long upload is done ~0.8 s sooner
  (``benchmarks/bench_service.py``, docs/benchmarks.md).
* A service that has processed a few long runs and kept what they freed stays ~1.3 GB
  resident while idle.

So while the service works (:func:`keep_freed_memory`) glibc serves blocks up to 64 MB from
its heap (a column of an hour's log is 29 MB; the upload's 135 MB buffer stays a mapping of
its own, returned when freed), does not trim it by itself and keeps one arena for every
thread (what one thread frees another reuses), and pyarrow allocates from that heap too (its
own mimalloc pool would keep the CSV parser's columns apart and hand them back at once).
64 MB and not more: keeping larger blocks as well would make uploads only slightly faster and
take the peak resident memory of successive hour-long uploads past the 1.5 GB target
(``benchmarks/bench_service.py``). :class:`IdleRelease` hands the free pages back
(``malloc_trim``) once nothing has been processed for a while. Where the C library is not
glibc nothing is changed.
"""

from __future__ import annotations

import ctypes
import threading
import time
from collections.abc import Callable

import pyarrow as pa


def _malloc_trim() -> Callable[[int], int] | None:
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return None
    trim = getattr(libc, "malloc_trim", None)
    if trim is None:
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


_TRIM = _malloc_trim()

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD, _M_ARENA_MAX = -1, -3, -8  # glibc's malloc.h
KEPT_BLOCK_BYTES = 1 << 26
"""While memory is kept: blocks up to this size come from the heap, and its free top is
trimmed by glibc itself only past it, B."""
KEPT_ARENAS = 1
"""While memory is kept: glibc arenas the threads share."""
RELEASE_AFTER_IDLE_S = 10.0
"""Default idle time after which kept memory is handed back, s (as jemalloc's decay)."""


def keep_freed_memory() -> bool:
    """Keep freed memory in the process (see the module's description): glibc's thresholds
    raised to :data:`KEPT_BLOCK_BYTES`, :data:`KEPT_ARENAS` arenas, pyarrow allocating with
    the C library. Process-wide and for the rest of its life; False where the C library is
    not glibc."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    pa.set_memory_pool(pa.system_memory_pool())
    return all(
        mallopt(option, value) == 1
        for option, value in (
            (_M_MMAP_THRESHOLD, KEPT_BLOCK_BYTES),
            (_M_TRIM_THRESHOLD, KEPT_BLOCK_BYTES),
            (_M_ARENA_MAX, KEPT_ARENAS),
        )
    )


def release_freed_memory() -> bool:
    """Hand the C allocator's free pages back to the operating system (glibc's
    ``malloc_trim(0)``, a few milliseconds); False where the C library has no such call."""
    if _TRIM is None:
        return False
    _TRIM(0)
    return True


class IdleRelease:
    """Hands freed memory back once the process has done no work for ``idle_s`` seconds.

    ``busy()`` is called when a piece of work (an upload, a run, a calibration) ends;
    ``release_if_idle()`` by a timer. ``idle_s`` 0 releases at once, at every ``busy()``
    (glibc's defaults: nothing kept).
    """

    def __init__(self, idle_s: float, release: Callable[[], bool] | None = None) -> None:
        self.idle_s = idle_s
        self._release_fn = release
        self._lock = threading.Lock()
        self._last_busy = time.monotonic()
        self._released = True

    def _release(self) -> bool:
        return (self._release_fn or release_freed_memory)()

    def busy(self) -> None:
        """Work has just ended: its freed memory is kept (or handed back now, ``idle_s`` 0)."""
        if self.idle_s <= 0:
            self._release()
            return
        with self._lock:
            self._last_busy = time.monotonic()
            self._released = False

    def release_if_idle(self) -> bool:
        """Hand memory back if there was work since the last release and none for
        ``idle_s``; True when it did."""
        with self._lock:
            if self._released or time.monotonic() - self._last_busy < self.idle_s:
                return False
            self._released = True
        self._release()
        return True
