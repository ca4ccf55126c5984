"""Linear algebra and optimisation: Laplacians (``laplacian``), the screened Poisson solver
of the Large-Steps reparameterisation (``screened``: ``(I + λL) x = b``, differentiable),
Jacobi-preconditioned CG (``pcg``) and uniform Adam (``optim``)."""
