"""Blender operators of the Micro-Mesh extension (thin glue around ``core``)."""
