"""Warp kernels and ``wp.func`` building blocks: no ensembles, no I/O.

Modules: ``common`` (shared funcs), ``lines`` (random spectra, bounds, prefix sums, min/max
tree), ``direct``, ``tree`` and ``edge`` (the three force algorithms). Importing them needs
Warp; use :func:`mdroll.devices.warp` to initialise it first.
"""
