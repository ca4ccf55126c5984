"""What this machine has: memory available to a new allocation now, and this process's peak
resident memory so far. None where the platform does not say."""
from __future__ import annotations

import ctypes
import os
import sys


def available_memory_bytes() -> float | None:
    """Memory a process can still take without swapping (Linux: MemAvailable; Windows:
    available physical memory; macOS, whose standard library does not say: three quarters of
    the physical memory)."""
    try:
        if sys.platform.startswith("linux"):
            with open("/proc/meminfo") as f:
                for line in f:
                    if line.startswith("MemAvailable:"):
                        return float(line.split()[1]) * 1024
            return None
        if sys.platform == "win32":
            return _windows_available()
        if sys.platform == "darwin":
            return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")) * 0.75
    except (OSError, ValueError, AttributeError):
        return None
    return None


def peak_resident_bytes() -> float | None:
    """This process's peak resident memory (the whole process: in Blender, Blender's too)."""
    try:
        import resource
    except ImportError:                   # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return float(peak if sys.platform == "darwin" else peak * 1024)   # bytes on macOS, KiB else


def _windows_available() -> float | None:
    class Status(ctypes.Structure):
        _fields_ = [("dwLength", ctypes.c_ulong), ("dwMemoryLoad", ctypes.c_ulong),
                    ("ullTotalPhys", ctypes.c_ulonglong), ("ullAvailPhys", ctypes.c_ulonglong),
                    ("ullTotalPageFile", ctypes.c_ulonglong),
                    ("ullAvailPageFile", ctypes.c_ulonglong),
                    ("ullTotalVirtual", ctypes.c_ulonglong),
                    ("ullAvailVirtual", ctypes.c_ulonglong),
                    ("ullAvailExtendedVirtual", ctypes.c_ulonglong)]

    status = Status()
    status.dwLength = ctypes.sizeof(Status)
    if not ctypes.windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(status)):
        return None
    return float(status.ullAvailPhys)
