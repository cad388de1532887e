"""Compiling alight's numba kernels before a mission's clock starts, and where they are cached.

The modules import one way (``tests/meta/test_layers.py`` checks it), each only those above it:

- :mod:`~alight.compile.cache`: numba's cache directory, keyed by the whole package's source; set by
  :mod:`alight`'s import before any kernel is defined, so it imports nothing.
- :mod:`~alight.compile.meter`: what numba compiles (CPU time per kernel) and which signatures Python
  calls first; numba's events only.
- :mod:`~alight.compile.parallel`: compiles the listed kernels (``kernels.json``) in helper processes.
- :mod:`~alight.compile.warmup`: flies each preset's warm-up mission (``python -m alight.compile.warmup``).
- :mod:`~alight.compile.kernel_list`: writes ``kernels.json`` by recording the warm-up flights
  (``python -m alight.compile.kernel_list --write``).

This ``__init__`` imports nothing: :mod:`alight` imports the cache module first of all.
"""
