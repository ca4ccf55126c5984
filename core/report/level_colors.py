"""One colour per subdivision level 0..7, blue -> red: the run report's, the N-panel's and the
result object's (``operators.writeback``)."""
import numpy as np

LEVEL_COLORS = np.array([[0.05, 0.10, 0.60], [0.05, 0.45, 0.80], [0.10, 0.70, 0.30],
                         [0.85, 0.80, 0.10], [0.90, 0.40, 0.05], [0.80, 0.05, 0.05],
                         [0.55, 0.0, 0.35], [0.3, 0.0, 0.2]])
