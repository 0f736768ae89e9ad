"""Rough-line generation, force batching over devices, dynamics and spectra."""
