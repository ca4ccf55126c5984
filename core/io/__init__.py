"""File formats and output files (no bpy)."""
