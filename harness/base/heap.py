"""The C library's heap kept between blocks of work instead of handed back to the kernel.

glibc's malloc serves a request of M_MMAP_THRESHOLD bytes or more (128 KiB at start) by a fresh
mmap, and gives the free top of its heap back to the kernel once it exceeds M_TRIM_THRESHOLD
(twice that). Its own rule raises both, up to 32 MiB and 64 MiB, but only once a large mmapped
block has been freed, which a process may never do. The batched kinematics and Newton-Euler
allocate and free arrays of 0.1 to 1 MiB for every block of states: below those values each of them
is mapped, faulted in page by page and handed back, block after block, which took a third of the
time of the torques from joint coordinates (docs/speed.md). `keep_heap` sets the two thresholds
where glibc's rule ends, once per process; the heap then keeps up to 64 MiB it freed at its top.
With another C library (macOS, Windows, musl) it does nothing.
"""

from __future__ import annotations

import sys

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # mallopt's parameters, <malloc.h>
MMAP_THRESHOLD = 32 << 20  # DEFAULT_MMAP_THRESHOLD_MAX of 64-bit glibc: where its rule stops
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD  # what its rule sets beside it

_kept: bool | None = None


def keep_heap() -> bool:
    """Set glibc's thresholds (above) once per process; True where they were set."""
    global _kept
    if _kept is None:
        _kept = sys.platform.startswith("linux") and _mallopt()
    return _kept


def _mallopt() -> bool:
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process' own C library
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    # 1 is success; musl's mallopt is a stub that returns 0
    return mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1 and mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
