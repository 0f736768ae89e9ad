"""Finding checks: the built-ins by name, ``package.module:function``, TOML files of checks and
the ``mdroll.checks`` entry-point group of installed packages; and running them.

A *check provider* is a :class:`~mdroll.validation.api.Check`, or a callable returning a Check,
a :class:`~mdroll.validation.api.CheckResult` or an iterable of them. The callable takes no
argument, or one: the :class:`~mdroll.validation.checks.Context` (sizes, seed, ensemble source)
that the built-ins take.

TOML schema (``mdroll validate --checks FILE.toml``): an array of tables ``[[check]]``, each

=======================  =========================================================================
key                      meaning
=======================  =========================================================================
``name``                 the check's name (string, required)
``prediction``           ``"package.module:function"``, a callable ``(x, params) -> PSD or scalar``
``comparison``           ``"ratio"`` (default), ``"slope"``, ``"period"`` or ``"peak"``
``band``                 ``[lo, hi)`` in ``band_unit`` (required)
``band_unit``            ``"q_min"`` (default), ``"rad/m"``, ``"omega_0"`` or ``"rad/s"``
``whole_periods``        band made of whole modulation periods pi/a (default false)
``allowance``, ``k``     the tolerance: allowance + k standard errors (defaults 0.05 and 3)
``quantity``             ``"force"`` (default) or ``"accel"``
``paired``               per-realization standard errors (default false)
``equation``,            labels of the result
``unit``, ``note``
``[check.spec]``         ``seed``, ``first``, ``realizations``, ``algorithm``, ``mode``,
                         ``boundary``, ``window`` of :class:`mdroll.EnsembleSpec`, and a table
                         ``[check.spec.params]`` of :class:`mdroll.Params` fields (SI units);
                         an ``n_real`` there is the spec's ``realizations``
``[check.reference]``    optional second ensemble for a scalar ratio: changes to ``spec``, same keys
=======================  =========================================================================

and, beside them, an optional top-level ``providers = ["package.module:function", ...]``.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import inspect
import os
import sys
from collections.abc import Iterable
from importlib.metadata import entry_points

from ..ensemble.spec import EnsembleSpec
from ..files import read_toml
from ..errors import ParameterError, PredictionError
from ..ensemble.realizations import COUNT_KEY, read_params
from .api import Band, Check, CheckResult
from .checks import CHECKS, SIZES, Context, ValidationSize
from .ensembles import EnsembleSource

#: The entry-point group of installed packages' check providers.
ENTRY_POINT_GROUP = "mdroll.checks"
CHECK_KEYS = {"name", "prediction", "comparison", "band", "band_unit", "whole_periods", "allowance", "k", "quantity",
              "paired", "equation", "unit", "note", "spec", "reference"}
#: A spec's keys in TOML (its roughness through the roughness fields of [check.spec.params]).
SPEC_KEYS = {f.name for f in dataclasses.fields(EnsembleSpec)} - {"roughness"}


def _import_from_working_directory(module_name: str):
    """Import ``module_name`` as ``python -m`` finds modules: the working directory first on the
    path (for the import only), so that a package in the current folder needs no installing."""
    here = os.getcwd()
    added = here not in sys.path and "" not in sys.path
    if added:
        sys.path.insert(0, here)
    try:
        return importlib.import_module(module_name)
    finally:
        if added:
            sys.path.remove(here)


def load_object(target: str):
    """The object named by ``"package.module:attribute"`` (looked up in the working directory
    first, as ``python -m`` does, then among the installed packages), or a ParameterError."""
    if not isinstance(target, str):
        raise ParameterError(f"check {target!r} is not a text of the form package.module:function")
    module_name, sep, attribute = target.partition(":")
    if not sep or not module_name or not attribute:
        raise ParameterError(f"check {target!r} is not of the form package.module:function")
    try:
        obj = _import_from_working_directory(module_name)
    except ImportError as exc:
        raise ParameterError(f"check {target!r}: cannot import {module_name!r} ({exc})") from None
    except SyntaxError as exc:
        raise ParameterError(f"check {target!r}: {exc.filename}, line {exc.lineno}: a syntax error ({exc.msg})") from None
    except SystemExit as exc:
        raise ParameterError(f"check {target!r}: importing {module_name!r} called sys.exit({exc.code!r})") from None
    except Exception as exc:  # a user's module may fail in any way at import: named, one line
        raise ParameterError(f"check {target!r}: importing {module_name!r} raised {type(exc).__name__}: {exc}") from None
    for part in attribute.split("."):
        if not hasattr(obj, part):
            raise ParameterError(f"check {target!r}: {module_name!r} has no attribute {attribute!r}")
        obj = getattr(obj, part)
    return obj


def installed_providers() -> dict:
    """The providers of the ``mdroll.checks`` entry points, by entry-point name."""
    out = {}
    for point in entry_points(group=ENTRY_POINT_GROUP):
        try:
            out[point.name] = point.load()
        except Exception as exc:  # an installed package's import error: named, one line
            raise ParameterError(f"entry point {point.name!r} ({point.value}) of group {ENTRY_POINT_GROUP!r} "
                                 f"failed to load: {type(exc).__name__}: {exc}") from None
    return out


#: The type each key of a [[check]] table must have (besides spec and reference, tables).
_KEY_TYPES = {"name": (str, "a text"), "prediction": (str, "a text package.module:function"),
              "comparison": (str, "a text"), "band_unit": (str, "a text"), "whole_periods": (bool, "true or false"),
              "allowance": ((int, float), "a number"), "k": ((int, float), "a number"),
              "quantity": (str, "a text"), "paired": (bool, "true or false"), "equation": (str, "a text"),
              "unit": (str, "a text"), "note": (str, "a text"), "spec": (dict, "a table"),
              "reference": (dict, "a table")}


def _check_types(table: dict, where: str) -> None:
    """Refuse a [[check]] value of the wrong type, naming the key and what it must be."""
    for key, (kind, text) in _KEY_TYPES.items():
        if key in table and (not isinstance(table[key], kind) or (kind != bool and isinstance(table[key], bool))):
            raise ParameterError(f"{where}: {key} = {table[key]!r} is not allowed: it must be {text}")
    band = table["band"]
    if not (isinstance(band, list) and len(band) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in band)):
        raise ParameterError(f"{where}: band = {band!r} is not allowed: it must be [lo, hi], two numbers")
    for part in ("spec", "reference"):
        params = table.get(part, {}).get("params", {})
        if not isinstance(params, dict):
            raise ParameterError(f"{where}: [{part}.params] = {params!r} is not allowed: it must be a table")


def _spec(table: dict, where: str) -> EnsembleSpec:
    unknown = set(table) - SPEC_KEYS
    if unknown:
        raise ParameterError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {', '.join(sorted(SPEC_KEYS))}")
    try:
        params, count = read_params(table.get("params", {}))
        table = {**table, "params": params}
        if count is not None and table.setdefault("realizations", count) != count:
            raise ParameterError(f"{where}: realizations = {table['realizations']!r} and {COUNT_KEY} = {count} in "
                                 "its params differ; give one of them")
        return EnsembleSpec(**table)
    except TypeError:
        raise ParameterError(f"{where}: a value of the wrong type (seed, first, realizations: integers; algorithm, "
                             "mode, boundary: texts; window: true or false; params: a table)") from None


def checks_from_toml(path) -> list[Check]:
    """The checks of a TOML file (schema in the module docstring) and its ``providers``."""
    data = read_toml(path, "checks file", ParameterError)
    unknown = set(data) - {"check", "providers"}
    if unknown:
        raise ParameterError(f"checks file {path}: unknown top-level key(s) {sorted(unknown)}; allowed: check, providers")
    names, tables = data.get("providers", []), data.get("check", [])
    if not isinstance(names, list) or not all(isinstance(t, str) for t in names):
        raise ParameterError(f"checks file {path}: providers = {names!r} is not allowed: it must be a list of texts "
                             "package.module:function")
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise ParameterError(f"checks file {path}: 'check' must be an array of tables [[check]], got {tables!r}")
    providers = [load_object(t) for t in names]
    for number, table in enumerate(tables, start=1):
        where = f"checks file {path}, check {number}"
        unknown = set(table) - CHECK_KEYS
        missing = {"name", "prediction", "band"} - set(table)
        if unknown or missing:
            raise ParameterError(f"{where}: " + (f"unknown key(s) {sorted(unknown)}" if unknown else
                                                  f"missing key(s) {sorted(missing)}"))
        _check_types(table, where)
        table = dict(table)
        spec = _spec(table.pop("spec", {}), where + " [spec]")
        reference = table.pop("reference", None)
        if reference is not None:
            merged = {**{k: v for k, v in spec.as_dict().items() if k in SPEC_KEYS},
                      **{k: v for k, v in reference.items() if k != "params"}}
            merged["params"] = {**spec.params.as_dict(), **reference.get("params", {})}
            if COUNT_KEY in merged["params"] and "realizations" not in reference:
                del merged["realizations"]  # the reference's own count, not the spec's
            reference = _spec(merged, where + " [reference]")
        lo, hi = table.pop("band")
        band = Band(float(lo), float(hi), table.pop("band_unit", "q_min"), table.pop("whole_periods", False))
        providers.append(Check(spec=spec, reference=reference, band=band,
                               prediction=load_object(table.pop("prediction")), **table))
    return providers


def _provided(provider, ctx: Context) -> list:
    """The Checks and CheckResults of one provider."""
    if isinstance(provider, (Check, CheckResult)):
        return [provider]
    if not callable(provider):
        raise ParameterError(f"check provider {provider!r} is neither a Check nor callable")
    name = getattr(provider, "__qualname__", repr(provider))
    try:
        items = provider(ctx) if inspect.signature(provider).parameters else provider()
        if isinstance(items, (Check, CheckResult)):
            return [items]
        if isinstance(items, (str, bytes, dict)) or not isinstance(items, Iterable):
            raise ParameterError(f"check provider {name!r} returned {items!r}, not a Check, a CheckResult or a "
                                 "list of them")
        items = list(items)
    except ParameterError:
        raise
    except SystemExit as exc:  # sys.exit in a provider must not end mdroll as a success
        raise PredictionError(f"check provider {name!r} called sys.exit({exc.code!r})") from None
    except Exception as exc:  # a user's provider may fail in any way: bad input, named
        raise PredictionError(f"check provider {name!r} raised {type(exc).__name__}: {exc}") from None
    bad = [i for i in items if not isinstance(i, (Check, CheckResult))]
    if bad:
        raise ParameterError(f"check provider {name!r} returned {bad[0]!r}, "
                             "not a Check or CheckResult")
    return items


def select(only=(), targets=(), files=(), installed: bool = False) -> list:
    """The providers to run: built-ins named in ``only``, ``module:function`` ``targets``, the
    checks of TOML ``files`` and, with ``installed``, the entry points; all built-ins if none."""
    unknown = [n for n in only if n not in CHECKS]
    if unknown:
        raise ParameterError(f"unknown check(s) {unknown}; valid ones are: {', '.join(CHECKS)}")
    providers = [CHECKS[n] for n in only] + [load_object(t) for t in targets]
    for path in files:
        found = checks_from_toml(path)
        if not found:
            raise ParameterError(f"checks file {path} holds no [[check]] table and no providers")
        providers += found
    if installed:
        found = list(installed_providers().values())
        if not found:
            raise ParameterError(f"no installed package declares checks (entry-point group {ENTRY_POINT_GROUP!r})")
        providers += found
    return providers or list(CHECKS.values())


def run_checks(size: str | ValidationSize = "quick", only=None, seed: int = 0, device: str = "cpu",
               progress: bool = False, providers=None, runner=None, cache=None) -> list[CheckResult]:
    """Run ``providers`` (default the built-ins named in ``only``, all without it; see
    :func:`select`) on ensembles of ``size`` (``"quick"``, ``"full"`` or a :class:`ValidationSize`)
    from ``device`` or ``runner``, through ``cache`` (an :class:`~mdroll.validation.cache.EnsembleCache`
    or None)."""
    if providers is None:
        providers = select(only or ())
    if isinstance(size, str):
        size = SIZES.rung(size)
    ctx = Context(size, seed, EnsembleSource(device, runner, cache, progress))
    results = []
    for provider in providers:
        for item in _provided(provider, ctx):
            results.append(item if isinstance(item, CheckResult) else item.run(ctx.source))
    for r in results:  # a NaN measurement fails its check; a NaN prediction is bad input
        if not (math.isfinite(r.predicted) and math.isfinite(r.tolerance)):
            raise PredictionError(f"check {r.name!r}: predicted {r.predicted!r} with tolerance {r.tolerance!r}: "
                                  "not finite")
    return results
