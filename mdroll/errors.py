"""The exceptions of mdroll, all in one place.

Every error that a user's input causes derives from :class:`MdrollError`: the command line turns
it into one line on stderr and exit code 2. Any other exception is a bug and shows as one.
"""

from __future__ import annotations


class MdrollError(Exception):
    """A user's error: its message is one line naming the parameter or file and what is allowed."""


class ParameterError(MdrollError, ValueError):
    """A parameter is out of range, of the wrong type or not finite.

    The message names the parameter, the value given and what is allowed. Also a
    :class:`ValueError`, as a bad value is.
    """


class DeviceError(MdrollError, ValueError):
    """A device that does not exist, or a CUDA run without the packages it needs."""


class NonFiniteError(MdrollError, FloatingPointError):
    """NaN or infinity in a force or spectrum; the message names the realization and stage."""


class PredictionError(ParameterError):
    """A check's prediction raised or returned a non-finite value."""


class UsageError(MdrollError):
    """Bad command-line input: an option, a file or a folder that cannot be used."""


class SchedulerLost(MdrollError):
    """A distributed run lost its Dask scheduler; the message names its address and where the
    finished work is kept."""
