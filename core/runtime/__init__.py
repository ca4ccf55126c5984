"""How the core runs: compiled kernels and their cache (``jit``), thread pools (``threads``),
memory (``memory``), the same numbers on every run on a GPU (``determinism``)."""
