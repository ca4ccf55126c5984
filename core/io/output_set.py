"""The files of one result, written as a set: all under temporary names first, then renamed
into place with the marker file last, so an interrupted run never leaves a set that looks
finished; output names unique within a run; the output folder checked before any work.
"""
from __future__ import annotations

import os
from pathlib import Path


class OutputError(ValueError):
    """An output folder or file that cannot be used."""


def output_names(inputs: list[Path]) -> list[str]:
    """One result name per input, unique within the run even on case-insensitive file
    systems: the file's stem, or ``stem_ext`` where two inputs share a stem (``a.obj`` and
    ``a.ply`` become ``a_obj`` and ``a_ply``), numbered if that is still taken."""
    stems = [p.stem for p in inputs]
    shared = {s.lower() for s in stems if sum(t.lower() == s.lower() for t in stems) > 1}
    names, taken = [], set()
    for p, stem in zip(inputs, stems):
        name = f"{stem}_{p.suffix.lstrip('.').lower()}" if stem.lower() in shared else stem
        base, k = name, 2
        while name.lower() in taken:
            name, k = f"{base}_{k}", k + 1
        taken.add(name.lower())
        names.append(name)
    return names


def check_output_folder(folder: Path) -> None:
    """Create ``folder`` if needed and make sure files can be written and renamed in it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        os.replace(probe, folder / f".write-test-{os.getpid()}.renamed")
        (folder / f".write-test-{os.getpid()}.renamed").unlink()
    except OSError as e:
        raise OutputError(f"cannot write to the output folder {folder}: "
                          f"{e.strerror or e}") from None


class OutputSet:
    """The files ``folder/name + suffix`` of one result. Write each to :meth:`temp`, then
    :meth:`commit`; :meth:`discard` (or leaving a ``with`` block by an exception) removes
    what was written. ``suffixes[-1]`` is the marker: renamed last, its presence means the
    set is complete. ``optional`` suffixes are files a result may have or not (the source's
    textures carried onto the maps): moved in with the others where written."""

    def __init__(self, folder: Path, name: str, suffixes: list[str],
                 optional: list[str] = ()):
        self.folder, self.name, self.suffixes = Path(folder), name, list(suffixes)
        self.optional = [s for s in optional if s not in self.suffixes]

    def final(self, suffix: str) -> Path:
        return self.folder / f"{self.name}{suffix}"

    def temp(self, suffix: str) -> Path:
        """Where to write the file that becomes :meth:`final` (same folder, same extension)."""
        if suffix not in self.suffixes and suffix not in self.optional:
            raise OutputError(f"'{suffix}' is not one of this set's files {self.suffixes}")
        return self.folder / f".{self.name}.partial-{os.getpid()}{suffix}"

    def existing(self) -> list[Path]:
        return [self.final(s) for s in self.suffixes + self.optional if self.final(s).exists()]

    def commit(self) -> None:
        missing = [s for s in self.suffixes if not self.temp(s).exists()]
        if missing:
            raise OutputError(f"{self.name}: {', '.join(missing)} was not written")
        marker = self.final(self.suffixes[-1])
        if marker.exists():            # replacing a finished set: unmark it first
            marker.unlink()
        for s in self.optional:        # an earlier result's extra files go with it
            if self.temp(s).exists():
                os.replace(self.temp(s), self.final(s))
            else:
                self.final(s).unlink(missing_ok=True)
        for s in self.suffixes:
            os.replace(self.temp(s), self.final(s))

    def discard(self) -> None:
        for s in self.suffixes + self.optional:
            self.temp(s).unlink(missing_ok=True)

    def __enter__(self) -> "OutputSet":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self.discard()
