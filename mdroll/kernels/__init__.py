"""Warp kernels and ``wp.func`` building blocks: no ensembles, no I/O.

Modules: ``common`` (shared funcs and constants), ``lines`` (random spectra, bounds, prefix
sums, min/max tree), one module per force algorithm (``direct``, ``tree``, ``edge``, ``sweep``:
its force kernel and, where it has one, its kernel of the coupled dynamics), ``dynamics`` (the
coupled dynamics of eq 13, made per algorithm) and ``spectra`` (series sums, the decoupled
response, PSD moments). The registry :mod:`mdroll.forces.registry` says how each force
algorithm is prepared and launched. Importing them needs Warp; use :func:`mdroll.devices.warp`
to initialise it first.
"""
