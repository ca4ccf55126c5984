"""The Python dependencies: which (``deps``: pins, their folder, the pip command), where
(``platforms``: which platforms have wheels, and why the others do not) and how they get
there in the background (``pip_job``; ``pip_output`` reads what pip prints). No ``bpy`` at
import; ``operators/install_op.py`` is the Blender operator over it."""
