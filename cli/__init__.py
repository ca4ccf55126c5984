"""The command line's own parts (``batch.py``): progress on a terminal or in a log, and the
final table of all inputs. No ``bpy``: they print what the workflow reports."""
