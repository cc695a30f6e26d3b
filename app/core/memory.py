"""Freed memory handed back to the operating system after a long run is processed.

An hour's log takes about a gigabyte while it is parsed, inverted and stored, most of it in
numpy arrays of 1-100 MB. glibc's allocator raises its mmap threshold after such arrays are
freed, so later ones of that size come from its heaps, and what is freed there stays in the
process: a service that processed a few long runs kept ~1.3 GB resident while idle, and the
next run's peak came on top (measured with ``benchmarks/bench_service.py --uploads 3``).
``malloc_trim`` returns those free pages; where the C library has no such call (not glibc)
nothing is done.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable


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


def release_freed_memory() -> bool:
    """Hand the C allocator's free pages back to the operating system (glibc's
    ``malloc_trim(0)``, a few milliseconds); False where the C library has no such call."""
    if _TRIM is None:
        return False
    _TRIM(0)
    return True
