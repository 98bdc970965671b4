"""The package version, in a module of its own so that no module needs the package root
(importing ``reachwise`` loads every layer and compiles the numba kernels)."""

__version__ = "0.1.0"
