"""Numba kernels and their public drivers: arrays (or named tuples of them) in, arrays out, no I/O.

Importing this package configures numba (cache folder, vector width) before numba itself is
imported; see ``surgopt.jit``.
"""
from surgopt.jit import configure_numba

configure_numba()
