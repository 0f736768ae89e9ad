"""Parameter sets given by a preset's name and ``KEY=VALUE`` text, as on a command line
(``--set track=PRESET``, ``--set track.pad_loss=0.3``): the one parser of such settings, and
:class:`Presettable`, the presets, copies and settings of the track's and the wheel's parameters.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping

from .errors import ParameterError


def split_setting(item: str, form: str = "KEY=VALUE") -> tuple[str, str]:
    """``"KEY=VALUE"`` as ``(KEY, VALUE)``, both stripped; no ``=``: ParameterError naming the
    ``form`` expected."""
    key, sep, value = item.partition("=")
    if not sep:
        raise ParameterError(f"setting {item!r} is not allowed: write {form}")
    return key.strip(), value.strip()


def parse_number(key: str, text) -> float:
    """The number ``text`` given for ``key`` (text, or a number as a TOML table gives it; not a
    bool), or ParameterError."""
    try:
        if isinstance(text, bool):
            raise ValueError
        return float(text)
    except (TypeError, ValueError):
        raise ParameterError(f"{key} = {text!r} is not allowed: it must be a number") from None


def parse_flag(key: str, text) -> bool:
    """The flag ``text`` given for ``key``: a bool (as a TOML table gives it) or the text ``true``
    or ``false`` (any case), or ParameterError."""
    if isinstance(text, bool):
        return text
    if isinstance(text, str) and text.strip().lower() in ("true", "false"):
        return text.strip().lower() == "true"
    raise ParameterError(f"{key} = {text!r} is not allowed: it must be true or false")


class Presettable:
    """For a frozen dataclass of parameters named ``<PREFIX>.<field>`` with presets: the class sets
    ``PREFIX`` (``"track"``), ``PRESETS`` (name -> field values), ``TEXT_FIELDS`` (the fields
    given as text) and ``FLAG_FIELDS`` (true or false); every other field a setting gives is a
    number."""

    PREFIX: str
    PRESETS: dict
    TEXT_FIELDS: tuple
    FLAG_FIELDS: tuple = ()

    @classmethod
    def preset(cls, name: str):
        """The preset ``name`` of ``PRESETS``."""
        if not isinstance(name, str) or name not in cls.PRESETS:
            raise ParameterError(f"{cls.PREFIX} = {name!r} is not allowed: choose one of {list(cls.PRESETS)}")
        return cls(**cls.PRESETS[name])

    def with_values(self, **values):
        """A copy with some fields changed (validated again); unknown names raise ParameterError."""
        names = [f.name for f in dataclasses.fields(self)]
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise ParameterError(f"{self.PREFIX}.{unknown[0]} is not allowed: the {self.PREFIX} keys are {names}")
        return dataclasses.replace(self, **values)

    @classmethod
    def from_settings(cls, settings: Mapping[str, str] | Iterable[str | tuple[str, str]]):
        """An instance from ``<PREFIX>=PRESET`` and ``<PREFIX>.KEY=VALUE`` settings (text, as on a
        command line), given as a mapping ``{"track.pad_loss": "0.3"}``, as ``"KEY=VALUE"`` strings
        or as (KEY, VALUE) pairs. The preset applies first (default: the class defaults), then the
        keys in order."""
        form = f"{cls.PREFIX}.KEY=VALUE or {cls.PREFIX}=PRESET"
        pairs = list(settings.items()) if isinstance(settings, Mapping) else [
            split_setting(s, form) if isinstance(s, str) else tuple(s) for s in settings]
        made = cls()
        for key, value in pairs:
            if key == cls.PREFIX:
                made = cls.preset(value)
        for key, value in pairs:
            if key != cls.PREFIX:
                name = key.removeprefix(f"{cls.PREFIX}.")
                made = made.with_values(**{name: value if name in cls.TEXT_FIELDS else parse_flag(key, value)
                                           if name in cls.FLAG_FIELDS else parse_number(key, value)})
        return made

    def as_dict(self) -> dict:
        """The fields as a plain dict."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
