"""The command line's own parts (``batch.py``): its options and checks, progress on a terminal
or in a log, the final table of all inputs, the Ray driver. None of them imports ``bpy``
itself: each input's Blender part is ``operators.headless``, which they configure (and import
only when the inputs run)."""
