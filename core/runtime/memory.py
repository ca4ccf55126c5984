"""Heap policy for the renderer's image-sized temporaries (glibc only).

One optimiser iteration allocates several image-sized arrays (75 MB each at 24 x 512² x 3
float32) and frees them again. glibc serves anything above its mmap threshold (at most 32 MB
by default) with a fresh mapping and unmaps it on free, so every iteration page-faults and
zero-fills those arrays anew: about 5% of an iteration at 1M triangles and 24 x 512² on two
cores. :func:`keep_large_allocations` raises the threshold so that the freed arrays are reused
from the heap, and :func:`release_memory` gives the unused heap back to the OS when a
construction ends. After the optimiser, whose buffers are the ones worth keeping,
:func:`map_large_allocations` gives arrays of 32 MB or more their own mappings again: the
fit's large temporaries of varied sizes, served from a heap that never shrinks, had left it
fragmented and the process's resident size growing with every fit round (the 1.07M-face
input: 5.9 GB at the end of the fit for a far smaller live set).

All act on the whole process, and the thresholds stay for the rest of it (glibc cannot go
back to its adaptive default); freed heap is only returned by ``map_large_allocations``,
which ``core.construct`` calls after the optimiser, and ``release_memory``, which it calls
after every construction. Where the C library is not glibc, or where the process allocates
through another allocator (Blender's Linux builds use jemalloc), they do nothing.
"""
from __future__ import annotations

import ctypes

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_LIMIT = 1 << 30  # allocations up to 1 GiB come from the heap
_KEEP = (1 << 31) - 1  # free heap kept before glibc trims it (the largest value mallopt takes)
_MAPPED = 32 << 20     # after the optimiser: allocations from 32 MB on are mapped
_TRIM = 128 << 10      # glibc's default trim threshold


def _glibc():
    try:
        libc = ctypes.CDLL(None)
    except OSError:
        return None
    if not (hasattr(libc, "mallopt") and hasattr(libc, "malloc_trim") and hasattr(libc, "gnu_get_libc_version")):
        return None
    return libc


def keep_large_allocations() -> bool:
    """Serve allocations up to 1 GiB from the heap and keep freed heap; True if applied."""
    libc = _glibc()
    if libc is None:
        return False
    return bool(libc.mallopt(_M_MMAP_THRESHOLD, _LIMIT)) and bool(libc.mallopt(_M_TRIM_THRESHOLD, _KEEP))


def map_large_allocations() -> bool:
    """Serve allocations of 32 MB or more (glibc's largest adaptive threshold) with mappings of
    their own, returned to the OS when freed, trim freed heap as glibc does by default and
    return the free heap now; True if applied."""
    libc = _glibc()
    if libc is None:
        return False
    ok = bool(libc.mallopt(_M_MMAP_THRESHOLD, _MAPPED)) \
        and bool(libc.mallopt(_M_TRIM_THRESHOLD, _TRIM))
    libc.malloc_trim(0)
    return ok


def release_memory() -> None:
    """Return the free heap to the OS (after a construction; cheap when there is none)."""
    libc = _glibc()
    if libc is not None:
        libc.malloc_trim(0)
