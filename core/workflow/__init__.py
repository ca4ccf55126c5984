"""The workflow without Blender, which the N-panel and ``batch.py`` both only configure: a
:class:`Job` (the reference and its base, cameras, settings with the preset's name, the
method) run into an :class:`~core.workflow.outcome.Outcome` (:func:`run`); for ``batch.py``
the result's files too (:class:`Outputs`, :func:`write_files`; the panel's File > Export
writes the same table's formats, ``core.io.formats``). Blender's part (its own file
formats, the scene, the ``.blend``) stays in ``operators/``."""
from .files import Outputs, write_files, write_formats, write_report
from .job import Cancelled, Job, run

__all__ = ["Cancelled", "Job", "Outputs", "run", "write_files", "write_formats",
           "write_report"]
