"""Reading pip's output: the progress a line announces, and the cause of a failure in words."""
from __future__ import annotations

import re
import sys

from .platforms import current

_DOWNLOAD = re.compile(r"^\s*(?:Downloading|Using cached) (\S+?)(?:-\d[^\s]*)?"
                       r"\.(?:whl|tar\.gz|zip)\s+\(([\d.]+) (kB|MB|GB)\)")
_COLLECT = re.compile(r"^\s*Collecting (\S+)")
_LOCAL = re.compile(r"^\s*Processing \S*?([A-Za-z0-9_.]+?)-\d[^\s/]*\.whl\s*$")  # a local wheel
_UNIT_MB = {"kB": 1e-3, "MB": 1.0, "GB": 1e3}


def line_progress(line: str) -> dict | None:
    """What one line of pip's output says of its progress: ``phase`` and ``package``, with
    ``mb`` (the size it announces) and ``fetched`` (a package arrived) where it says so;
    None for the other lines."""
    m = _DOWNLOAD.match(line)
    if m:
        return {"phase": "downloading", "package": m.group(1), "fetched": True,
                "mb": float(m.group(2)) * _UNIT_MB[m.group(3)]}
    m = _LOCAL.match(line)
    if m:
        return {"phase": "downloading", "package": m.group(1), "fetched": True, "mb": 0.0}
    m = _COLLECT.match(line)
    if m:
        return {"phase": "downloading", "package": m.group(1)}
    if line.startswith("Installing collected packages"):
        return {"phase": "installing", "package": line.split(":", 1)[-1].strip()[:60]}
    return None


def platform_text() -> str:
    """This machine in words, as a failure message names it (``platforms.current``)."""
    import platform

    here = current()
    name = here.name if here is not None else f"{platform.system()} {platform.machine()}"
    return f"{name}, Python {sys.version_info[0]}.{sys.version_info[1]}"


_NETWORK = ("NewConnectionError", "Failed to establish a new connection",
            "Name or service not known",
            "Temporary failure in name resolution", "Network is unreachable", "ConnectionError",
            "ReadTimeoutError", "ConnectTimeoutError", "getaddrinfo failed",
            "No connection could be made", "ProxyError", "SSLError")


def failure_cause(lines: list[str]) -> str:
    """The cause of a failed pip run, in words, from its output."""
    text = "\n".join(lines)
    if "No space left on device" in text or "[Errno 28]" in text:
        return "the disk is full: pip could not write the packages (about 1.4 GB are needed)"
    if "Permission denied" in text or "[Errno 13]" in text:
        return "no permission to write the dependency folder or pip's temporary files"
    missing = re.search(r"No matching distribution found for (\S+)", text)
    if any(s in text for s in _NETWORK):
        return ("no network: pip could not reach the package index (check the connection, a "
                "proxy or a firewall; Blender's online access must be on)")
    if missing and "(from versions: none)" in text:
        return (f"pip found no version of {missing.group(1)} at all: the package index cannot "
                "be reached (no network, a proxy, a firewall) or has nothing for "
                + platform_text())
    if missing:
        return (f"no package for this platform: {missing.group(1)} has no wheel for "
                f"{platform_text()} (see the README's supported platforms)")
    errors = [ln.strip() for ln in lines if ln.strip().startswith("ERROR")]
    return errors[-1] if errors else (lines[-1].strip() if lines else "pip printed nothing")
