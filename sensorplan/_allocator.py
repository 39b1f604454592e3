"""Keep freed memory in the process instead of handing it back to the system after every large array.

glibc's malloc serves arrays above its mmap threshold (128 KiB to 32 MiB,
adjusted as it goes) with fresh mappings and returns them on free, and
trims the top of the heap when more than the trim threshold is free.  The
design at network scale allocates and frees arrays of tens of MB thousands
of times (dense blocks a batch at a time, products of the structured
blocks); every new mapping is zero-filled by the kernel page by page.  With
the mmap threshold at 256 MiB and the trim threshold at 1 GiB the same
pages are reused: ``recommend --criterion D`` at N = 400, C = 3,000, R = 20
spent 15.2 s of 118 CPU seconds in the kernel, 2.4 s with the pages kept
(peak memory 2.17 -> 2.42 GiB; studies/benchmarks/bench_network.py).

The command line owns its process and tunes it at start; a program that
calls the API may call :func:`keep_freed_memory` itself.  Elsewhere than on
glibc (macOS, Windows, musl) nothing changes.

Owns: keep_freed_memory.  May import: nothing of the package.
"""

import ctypes
import ctypes.util

__all__ = ["keep_freed_memory", "MMAP_THRESHOLD", "TRIM_THRESHOLD"]

MMAP_THRESHOLD = 256 * 2**20  # arrays above this size still get their own mapping (returned at once)
TRIM_THRESHOLD = 2**30  # free memory at the heap's top kept up to this size
TOP_PAD = 64 * 2**20  # extra obtained from the system each time the heap grows

# mallopt parameter numbers (glibc malloc.h)
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3


def keep_freed_memory():
    """Tune glibc's malloc to reuse freed pages (see the module docstring); True if it was tuned."""
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc: no mallopt
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    done = [mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD), mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD),
            mallopt(_M_TOP_PAD, TOP_PAD)]
    return all(flag == 1 for flag in done)
