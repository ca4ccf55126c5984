"""The table of base builders: the ways a base mesh is made from the source. The setting
``base_method`` (``batch.py --base-method``) chooses the one a construction without a base
uses; the panel's Make Base offers every row (its Method menu). Trimesh's registries are the
model: adding a builder is its module and one :func:`register` row.

A builder takes what its caller holds of the source. ``"arrays"``: the source as a
:class:`~core.mesh.TriMesh` in world space; such a builder runs inside the construction, in
any thread (``collapse``: the core's topology-keeping, error-bounded edge collapse). A row
that takes ``"object"`` works on the source's Blender object: the glue implements it
(:func:`implement`; Blender's Decimate modifier, ``operators/bl_decimate.py``) and runs it in
Blender's main thread (Make Base; ``batch.py``'s input before its construction). A
construction asked for such a base without one refuses, saying so. The panel's Construct
without a base builds with ``collapse``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

ARRAYS, OBJECT = "arrays", "object"


@dataclass(frozen=True)
class BaseBuilder:
    """One row: ``key`` (the setting's value), ``label`` and ``description`` (what the panel
    and ``batch.py --help`` show), ``takes`` (:data:`ARRAYS` or :data:`OBJECT`) and
    ``build``: for :data:`ARRAYS` ``build(reference, settings, progress, should_stop) ->
    core.base.BaseMesh`` (``progress(fraction)``); for :data:`OBJECT` ``build(source_object,
    settings, **options) -> (TriMesh, UVs at the triangles' corners or None)``; None where
    nothing here implements it (Blender's builders outside Blender)."""

    key: str
    label: str
    description: str
    takes: str
    build: Callable | None = None


BUILDERS: dict[str, BaseBuilder] = {}


def register(builder: BaseBuilder) -> BaseBuilder:
    """Add ``builder`` to the table (replacing a row of the same key)."""
    if builder.takes not in (ARRAYS, OBJECT):
        raise ValueError(f"a base builder takes {ARRAYS!r} or {OBJECT!r}")
    BUILDERS[builder.key] = builder
    return builder


def implement(key: str, build: Callable) -> BaseBuilder:
    """Give the row ``key`` its ``build`` (the glue's, for a builder of Blender objects)."""
    return register(replace(get(key), build=build))


def get(key: str) -> BaseBuilder:
    """The row of ``key``; ValueError naming the builders there are."""
    if key not in BUILDERS:
        raise ValueError(f"unknown base method {key!r}: {', '.join(BUILDERS)}")
    return BUILDERS[key]


def _collapse(reference, settings, progress=None, should_stop=None):
    from .build import base_for

    return base_for(reference, settings, progress, should_stop)


register(BaseBuilder("collapse", "Faithful",
                     "Edge collapse that keeps the topology (genus, parts, holes), bounds the "
                     "distance to the source and keeps triangles well shaped", ARRAYS, _collapse))
register(BaseBuilder("blender", "Decimate",
                     "Blender's Decimate modifier (symmetry, vertex group weights), with the "
                     "source's UVs", OBJECT))
