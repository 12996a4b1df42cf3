"""Numba kernels and their public drivers: arrays (or named tuples of them) in, arrays out, no I/O.

Importing this package does nothing; each kernel module compiles with ``surgopt.jit.njit``, which configures
numba (cache folder, vector width) before numba itself is first imported; see ``surgopt.jit``.
"""
