"""Experiments by name: the one registry mechanism of the analyses (checks, studies, sections)."""

from __future__ import annotations

from ..errors import ParameterError


class Registry(dict):
    """Named experiments in the order they were added; ``kind`` names them in errors ("study",
    "check"). ``registry.named(name)`` is the entry or a one-line
    :class:`~mdroll.errors.ParameterError`; :meth:`unknown` lists names not in it."""

    def __init__(self, kind: str, entries=()):
        super().__init__()
        self.kind = kind
        for name, entry in entries:
            self.add(name, entry)

    def add(self, name: str, entry):
        """Register ``entry`` under ``name`` (a name is registered once) and return it."""
        if name in self:
            raise ValueError(f"{self.kind} {name!r} is registered twice")
        self[name] = entry
        return entry

    def named(self, name: str):
        """The entry ``name``, or ParameterError naming the registered ones."""
        if name not in self:
            raise ParameterError(f"{self.kind} = {name!r} is not allowed: choose one of {', '.join(self)}")
        return self[name]

    def unknown(self, names) -> list:
        """The names of ``names`` that are not registered, sorted."""
        return sorted(set(names) - set(self))
