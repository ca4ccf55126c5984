"""Base-mesh building: topology-keeping, error- and quality-bounded edge-collapse decimation
(:func:`build_base`, :func:`base_for`), with a report of what it made; the table of base
builders (``builders``: the setting ``base_method``)."""
from . import builders
from .build import BaseError, BaseMesh, base_for, build_base, target_faces
from .decimate import DecimateCancelled, decimate
from .topology import Topology, differences, topology

__all__ = ["BaseError", "BaseMesh", "DecimateCancelled", "Topology", "base_for", "build_base",
           "builders", "decimate", "differences", "target_faces", "topology"]
