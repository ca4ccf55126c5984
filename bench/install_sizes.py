"""Download size of Install Dependencies per platform: the pinned set (``install/deps.py``)
and everything it pulls in, resolved for each supported platform's wheel tags and marker
environment (``install/platforms.py``), with the sizes the package index lists.

pip cannot do this for another platform (it judges dependency markers by the machine it runs
on), so this resolves by itself: PyPI's JSON simple pages (PEP 691) for the files and their
sizes, each chosen wheel's metadata (PEP 658) for its dependencies, the newest version that
satisfies every specifier seen and has a wheel for the platform. torch comes from PyTorch's
CPU index where it can be reached (what Install Dependencies fetches by default), else from
PyPI (on Linux that is the CUDA build: said in the table).

    python bench/install_sizes.py [--platforms NAME ...] [--json FILE]

Needs the network; nothing is installed or downloaded beyond the index pages and metadata.
"""
from __future__ import annotations

import io
import json
import urllib.error
import urllib.request
import zipfile
from functools import lru_cache

from _common import parser, print_table, write_json

from install import deps, platforms

PYPI = "https://pypi.org/simple"
_ACCEPT = {"Accept": "application/vnd.pypi.simple.v1+json"}


def _get(url: str, headers: dict | None = None) -> bytes:
    req = urllib.request.Request(url, headers=headers or {})
    with urllib.request.urlopen(req, timeout=60) as r:
        return r.read()


@lru_cache(maxsize=None)
def files(index: str, name: str) -> tuple:
    """The files an index lists for a project: (filename, url, size) (size None if unlisted)."""
    page = json.loads(_get(f"{index}/{name}/", _ACCEPT))
    return tuple((f["filename"], f["url"], f.get("size")) for f in page["files"]
                 if not f.get("yanked"))


@lru_cache(maxsize=None)
def requires(url: str) -> tuple[str, ...]:
    """A wheel's Requires-Dist lines, from its metadata file (PEP 658), or from the wheel
    itself where the index has no metadata file for it."""
    url = url.split("#")[0]
    try:
        text = _get(url + ".metadata").decode("utf-8", "replace")
    except urllib.error.HTTPError:
        with zipfile.ZipFile(io.BytesIO(_get(url))) as z:
            name = next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))
            text = z.read(name).decode("utf-8", "replace")
    return tuple(line.split(":", 1)[1].strip() for line in text.splitlines()
                 if line.startswith("Requires-Dist:"))


def supported_tags(p: platforms.Platform) -> set:
    """The wheel tags a CPython 3.11 on platform ``p`` installs, as ``packaging.tags.Tag``s."""
    from packaging import tags

    plats = []
    for t in p.tags:
        if t.startswith("macosx_"):
            major, _, arch = t[len("macosx_"):].split("_", 2)
            plats += list(tags.mac_platforms((int(major), 0), arch))
        elif "linux" in t:
            arch = t.split("_", 3)[-1] if t.startswith("manylinux_") else t.split("_", 1)[1]
            plats += [f"manylinux_2_{m}_{arch}" for m in range(28, 4, -1)]
            plats += [f"manylinux2014_{arch}", f"manylinux2010_{arch}", f"manylinux1_{arch}"]
        else:
            plats.append(t)
    return (set(tags.cpython_tags((3, 11), ["cp311", "abi3", "none"], plats))
            | set(tags.compatible_tags((3, 11), "cp311", plats)))


def pick(candidates, spec, tagset):
    """The newest (version, filename, url, size) among wheels that match ``spec`` and
    ``tagset``; None if there is none."""
    from packaging.utils import parse_wheel_filename

    best = None
    for filename, url, size in candidates:
        if not filename.endswith(".whl"):
            continue
        try:
            _, version, _, wtags = parse_wheel_filename(filename)
        except ValueError:
            continue
        if version.is_prerelease or version not in spec or not (wtags & tagset):
            continue
        if best is None or version > best[0]:
            best = (version, filename, url, size)
    return best


def pinned(p: platforms.Platform) -> list[str]:
    """What Install Dependencies asks pip for on platform ``p``."""
    return platforms.requirements_for(deps.pins(), p.env)


def resolve(p: platforms.Platform, torch_index: str | None, reqs: list[str] | None = None) -> dict:
    """{name: (version, filename, url, size)} of the closure of ``reqs`` (default: the pinned
    set) on platform ``p``."""
    from packaging.requirements import Requirement
    from packaging.specifiers import SpecifierSet
    from packaging.utils import canonicalize_name

    env = dict(p.env, extra="")
    tagset = supported_tags(p)
    queue = [(r, "") for r in (pinned(p) if reqs is None else reqs)]
    specs: dict = {}
    chosen: dict = {}
    while queue:
        text, extra = queue.pop()
        req = Requirement(text)
        if req.marker is not None and not req.marker.evaluate(dict(env, extra=extra)):
            continue
        name = canonicalize_name(req.name)
        specs[name] = specs.get(name, SpecifierSet()) & req.specifier
        index = torch_index if name == "torch" and torch_index else PYPI
        best = pick(files(index, name), specs[name], tagset)
        if best is None:
            raise SystemExit(f"{p.name}: no wheel of {name}{specs[name]}")
        new = name not in chosen or chosen[name][1] != best[1]
        chosen[name] = (str(best[0]), best[1], best[2], best[3])
        if new or req.extras:
            for dep in requires(best[2]):
                for e in (req.extras or {""}):
                    queue.append((dep, e))
    return chosen


def without_cuda(p: platforms.Platform, chosen: dict) -> dict:
    """Linux without PyTorch's CPU index: the closure of the pinned set with torch's wheel
    replaced by the dependencies every torch build has (those without a marker), so the rest
    of a CPU install can be sized; torch itself is left out."""
    torch_deps = [r for r in requires(chosen["torch"][2]) if ";" not in r]
    rest = [r for r in pinned(p) if not r.startswith("torch")]
    return resolve(p, None, rest + torch_deps)


def cpu_torch_index() -> str | None:
    try:
        files(deps.TORCH_CPU_INDEX, "torch")
        return deps.TORCH_CPU_INDEX
    except OSError:
        return None


def main() -> None:
    ap = parser(__doc__.split("\n\n")[0])
    ap.add_argument("--platforms", nargs="+", default=None, help="platform names (default: "
                    "every supported one)")
    args = ap.parse_args()
    cpu = cpu_torch_index()
    rows = []
    for p in platforms.PLATFORMS:
        if not p.supported or (args.platforms and p.name not in args.platforms):
            continue
        linux = p.env["sys_platform"] == "linux"
        chosen = resolve(p, cpu if linux else None)
        mb = {n: (c[3] or 0) / 1e6 for n, c in chosen.items()}
        row = {"platform": p.name, "wheels": len(chosen), "download_mb": round(sum(mb.values())),
               "torch_mb": round(mb["torch"]),
               "largest": ", ".join(f"{n} {v:.0f}" for n, v in
                                    sorted(mb.items(), key=lambda kv: -kv[1])[:4]),
               "torch": chosen["torch"][1],
               "unsized": sorted(n for n, c in chosen.items() if c[3] is None)}
        if linux and cpu is None:       # PyPI's Linux torch is the CUDA build
            rest = without_cuda(p, chosen)
            row["torch"] += " (PyPI's CUDA build: PyTorch's CPU index was not reachable)"
            row["without_torch_cpu_mb"] = round(sum((c[3] or 0) for c in rest.values()) / 1e6)
        rows.append(row)
        print(f"{p.name}: {rows[-1]['download_mb']} MB in {len(chosen)} wheels", flush=True)
    print_table(rows, title="Install Dependencies: download per platform (MB)")
    write_json(args.json, rows)


if __name__ == "__main__":
    main()
