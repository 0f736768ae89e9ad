"""Wheel models in the frequency domain: the rigid mass and the modal wheel's radial receptance.

numpy only; imports :mod:`mdroll.physics` and :mod:`mdroll.params` and nothing above.
"""

from .parameters import KINDS, PRESETS, SOURCES, STANDARD_920_MODES, Wheel
