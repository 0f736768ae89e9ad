"""Warp kernels and ``wp.func`` building blocks: no ensembles, no I/O.

Modules: ``common`` (shared funcs and constants), ``intrinsics`` (the CUDA intrinsics: shared
atomics, loads and stores by address, barriers, shuffles, the clock), ``lines`` (random spectra,
bounds, min/max tree), one module per force algorithm (``direct``, ``tree``, ``edge``; the sweep by
form: ``sweep_stream``, ``sweep_sequential``, ``sweep_coupled``): its force kernel and, where it
has one, its kernel of the coupled dynamics, ``dynamics`` (the coupled dynamics of eq 13, made per
algorithm), ``modal`` (its modal contact point) and ``moments`` (series sums, the decoupled
response, PSD moments). The registry :mod:`mdroll.forces.registry` says how each force algorithm is
prepared and launched. Importing them needs Warp; use :func:`mdroll.devices.warp` to initialise it
first.
"""
