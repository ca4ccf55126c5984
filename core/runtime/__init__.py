"""How the core runs: compiled kernels and their cache (``jit``), thread pools (``threads``),
memory (``memory``)."""
