"""What every command shares: the parser class whose errors are one line, the options that several
commands take (parameters from ``--set``/TOML/presets, sizes, output, clusters), and the output
directory: checked, created and locked before any work."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime
import fcntl
import os
import re
import secrets
import sys
import tempfile
from pathlib import Path

from ..errors import MdrollError, ParameterError, UsageError
from ..files import read_toml
from ..settings import split_setting
from ..track import Track
from ..wheel import Wheel
from ..ensemble.realizations import COUNT_KEY, read_params
from ..params import TEXT_FIELDS, Params

#: The keys of ``--set`` and a config file: the fields of :class:`~mdroll.Params` and the run's
#: realization count :data:`~mdroll.ensemble.realizations.COUNT_KEY` (``n_real``).
PARAM_NAMES = tuple(f.name for f in dataclasses.fields(Params)) + (COUNT_KEY,)
PRESETS = {
    # a small ensemble for a laptop CPU
    "quick": {"L": 0.2, "n_real": 8},
}
#: The lock file a live run holds (fcntl.flock) in its output directory.
LOCK = ".mdroll.lock"
_held_locks: list[int] = []


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are a :class:`UsageError` (one line, exit 2, no usage
    dump), and that takes a negative number as an option's value (``--seed -1``, ``--dx -1e-3``,
    ``--segment -inf``) as well as ``--opt=-x``: no option of mdroll looks like a number."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|nan)$", re.IGNORECASE)

    def error(self, message):
        if message.endswith("expected one argument"):
            message += " (a value starting with '-' is given as --option=VALUE)"
        raise UsageError(message)


# ----------------------------------------------------------------------------- options
def param_options(p) -> None:
    """``--config``, ``--set`` and ``--preset``: the run's :class:`~mdroll.Params` and realization
    count (:func:`build_params`)."""
    p.add_argument("--config", metavar="FILE.toml", help="parameters from a TOML file")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="set one parameter (repeatable), SI units")
    p.add_argument("--preset", choices=sorted(PRESETS), help="quick: L = 0.2 m, 8 realizations")


def device_option(p, what: str = "auto, cpu, cuda or cuda:N") -> None:
    """``--device`` (default auto, :func:`mdroll.devices.resolve_device`); ``what``: its help."""
    p.add_argument("--device", default="auto", help=what)


def size_options(p, quick: str, full: str) -> None:
    """``--quick`` (the default) or ``--full``, into ``args.size``."""
    size = p.add_mutually_exclusive_group()
    size.add_argument("--quick", dest="size", action="store_const", const="quick", help=quick)
    size.add_argument("--full", dest="size", action="store_const", const="full", help=full)


def output_options(p) -> None:
    """``--out``, ``--force`` and ``--no-progress``."""
    p.add_argument("--out", help="output directory (default mdroll-out/<command>-<timestamp>)")
    p.add_argument("--force", action="store_true", help="write into an existing output directory")
    p.add_argument("--no-progress", action="store_true")


def cluster_options(p) -> None:
    """``--workers N`` and ``--scheduler ADDRESS``: where a command's ensembles run (mdroll.distributed)."""
    p.add_argument("--workers", type=int, metavar="N", help="run on a local Dask cluster of N worker processes "
                   "(one per GPU on a GPU machine, --device cpu for CPU processes)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on an existing Dask cluster (tcp://host:8786)")
    p.add_argument("--verbose", action="store_true", help="show Dask's informational logs")


@contextlib.contextmanager
def cluster_runner(args):
    """The runner that ``--workers``/``--scheduler`` ask for (a :class:`mdroll.distributed.DaskRunner`
    for ``run_specs(..., runner=)``; set its ``checkpoint`` to keep the units), or None to run in
    this process; and the device the ensembles then run on (a local cluster pins one worker to
    each GPU, which it sees as cuda:0)."""
    if args.workers is None and args.scheduler is None:
        yield None, args.device
        return
    option = "--workers" if args.workers is not None else "--scheduler"
    # imported here for start-up cost: Dask loads only for a command that asks for a cluster
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError(f"{option} needs Dask distributed, which is not installed: "
                         "pip install 'mdroll[distributed]'") from None
    from ..distributed import DaskRunner, connect

    device = args.device if args.scheduler is not None or args.device == "cpu" else "auto"
    with connect(args.workers, args.scheduler, args.device, getattr(args, "verbose", False)) as client:
        yield DaskRunner(client), device


def progress_printer(args):
    """A function that prints one progress line on stderr, or does nothing with ``--no-progress``."""
    if args.no_progress:
        return lambda text: None
    return lambda text: print(text, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- parameters
def _parse_value(key: str, text: str):
    if key not in PARAM_NAMES:
        raise UsageError(f"unknown parameter {key!r}; valid ones are: {', '.join(PARAM_NAMES)}")
    if key in TEXT_FIELDS:
        return text
    try:
        if key == COUNT_KEY:
            return int(text)
        return float(text)
    except ValueError:
        kind = "an integer" if key == COUNT_KEY else "a number"
        raise UsageError(f"--set {key}={text}: not {kind}") from None


#: The config file's tables of the track and the wheel (:func:`config_structures`).
STRUCTURE_TABLES = ("track", "wheel")


def load_config(path: str) -> dict:
    """Parameters from a TOML file: top-level keys, or a ``[params]`` table alone, beside which
    only the ``[track]`` and ``[wheel]`` tables may stand (:func:`config_structures`); anything
    else (unknown keys, other tables, top-level keys beside ``[params]``, a ``params`` that is not
    a table) is refused, naming the key."""
    data = {k: v for k, v in read_toml(path, "config file", UsageError).items() if k not in STRUCTURE_TABLES}
    if "params" in data:
        if not isinstance(data["params"], dict):
            raise UsageError(f"config file {path}: 'params' must be a [params] table of parameters, "
                             f"got {data['params']!r}")
        beside = sorted(set(data) - {"params"})
        if beside:
            raise UsageError(f"config file {path}: {beside} beside the [params] table; put every parameter in it")
        data = data["params"]
    tables = sorted(key for key, value in data.items() if isinstance(value, dict))
    if tables:
        raise UsageError(f"config file {path}: unknown table(s) {tables}; only [params], [track] and [wheel] are read")
    unknown = sorted(set(data) - set(PARAM_NAMES))
    if unknown:
        raise UsageError(f"config file {path}: unknown parameter(s) {unknown}; valid ones are: {', '.join(PARAM_NAMES)}")
    return data


def config_structures(path: str) -> dict[str, list]:
    """The ``[track]`` and ``[wheel]`` tables of a TOML config file as settings, ``{"track":
    [("track", PRESET), ("track.KEY", value), ...], "wheel": [...]}``: ``preset = "NAME"`` is
    ``--set track=NAME``, every other key ``--set track.KEY=VALUE``; a ``track`` or ``wheel``
    that is not a table is refused."""
    data = read_toml(path, "config file", UsageError)
    settings: dict[str, list] = {name: [] for name in STRUCTURE_TABLES}
    for name in STRUCTURE_TABLES:
        table = data.get(name, {})
        if not isinstance(table, dict):
            raise UsageError(f"config file {path}: '{name}' must be a [{name}] table of keys, got {table!r}")
        settings[name] = [(name if key == "preset" else f"{name}.{key}", value) for key, value in table.items()]
    return settings


def build_params(args, base: dict | None = None) -> tuple[Params, int | None]:
    """The parameters of ``base``, then the preset, the config file and ``--set`` on top, and the
    realization count: ``--realizations`` if given (it wins over an ``n_real`` of the others), else
    the last ``n_real`` of those, else None (the run's default)."""
    values: dict = dict(base or {})
    if getattr(args, "preset", None):
        values.update(PRESETS[args.preset])
    if getattr(args, "config", None):
        values.update(load_config(args.config))
    for key, text in _settings(args):
        if _structure(key):
            continue  # the track's and the wheel's: :func:`build_structures`
        values[key] = _parse_value(key, text)
    if getattr(args, "realizations", None) is not None:
        if args.realizations < 1:
            raise UsageError(f"--realizations {args.realizations}: the number of realizations must be at least 1")
        values[COUNT_KEY] = args.realizations
    return read_params(values)


def _settings(args) -> list[tuple[str, str]]:
    """The ``--set`` items as (KEY, VALUE): :func:`mdroll.settings.split_setting`."""
    return [split_setting(item, "--set KEY=VALUE") for item in getattr(args, "set", None) or []]


def _structure(key: str) -> str | None:
    """``"track"`` or ``"wheel"`` for a ``--set`` key of theirs (``track=PRESET``, ``track.KEY``), else None."""
    head = key.split(".", 1)[0]
    return head if head in ("track", "wheel") else None


def build_structures(args):
    """The run's (track, wheel) from the config file's ``[track]`` and ``[wheel]`` tables
    (:func:`config_structures`), then ``--set track=PRESET``, ``track.KEY=VALUE``,
    ``wheel=PRESET`` and ``wheel.KEY=VALUE`` on top (None where neither gives any):
    :meth:`mdroll.settings.Presettable.from_settings` of :class:`~mdroll.track.Track` and
    :class:`~mdroll.wheel.Wheel`, each preset first, then the keys in order. A bad key or value
    of the file names the file."""
    path = getattr(args, "config", None)
    tables = config_structures(path) if path else {}
    settings = _settings(args)
    made = []
    for kind in (Track, Wheel):
        from_file = tables.get(kind.PREFIX, [])
        try:
            kind.from_settings(from_file)
        except ParameterError as exc:
            raise UsageError(f"config file {path}: [{kind.PREFIX}] {exc}") from None
        own = from_file + [(key, text) for key, text in settings if _structure(key) == kind.PREFIX]
        made.append(kind.from_settings(own) if own else None)
    return tuple(made)


def rigid_wheel_mass(args, params: Params, wheel):
    """``(params, wheel)`` with one mass for the rigid wheel, which is the run's mass m (eq 13):
    ``wheel.mass`` given (``--set`` or the config file's ``[wheel]`` table) sets m, and an m given
    beside it that differs is refused (ParameterError); otherwise the rigid wheel takes m. A modal
    wheel (its unsprung mass is its own) and no wheel are returned as they are."""
    if wheel is None or wheel.kind != "rigid":
        return params, wheel
    path = getattr(args, "config", None)
    set_keys = [key for key, _ in _settings(args)]
    if "wheel.mass" not in set_keys + [key for key, _ in (config_structures(path)["wheel"] if path else [])]:
        return params, wheel.with_values(mass=params.m)
    m_given = "m" in set_keys or bool(path and "m" in load_config(path))
    if m_given and params.m != wheel.mass:
        raise ParameterError(f"wheel.mass = {wheel.mass:g} kg is not allowed with m = {params.m:g} kg: the rigid "
                             "wheel's mass is the run's m; give one of them")
    return params.replace(m=wheel.mass), wheel


def format_value(value) -> str:
    """A parameter's value for a table: 6 significant digits for floats."""
    return f"{value:.6g}" if isinstance(value, float) else str(value)


@contextlib.contextmanager
def reading(what: str, path):
    """Around a reader of a user's file: a file it cannot open or decode (its OSError or ValueError,
    where it raised no :class:`MdrollError` of its own) ends in one line naming the file."""
    try:
        yield
    except MdrollError:
        raise
    except OSError as exc:
        raise UsageError(f"{what} {str(path)!r} cannot be read: {exc.strerror or 'an input/output error'}") from None
    except ValueError:
        raise UsageError(f"{what} {str(path)!r} cannot be read: it is not in a format its option reads (see "
                         "mdroll COMMAND --help)") from None


# ----------------------------------------------------------------------------- output
def output_dir(args, clear: tuple[str, ...] = ()) -> Path:
    """The output directory, checked, created and locked before any work: ``--out`` (an existing
    non-empty one only with ``--force``, which removes the files in ``clear``), or a new
    ``mdroll-out/<command>-<timestamp>-<pid>-<random>``, made by one ``mkdir`` (so two runs
    started in the same second never share it)."""
    if args.out:
        out = Path(args.out)
        check_output(args)
        _make_directory(out, "--out", exist_ok=True)
        lock(out, "--out")
        for name in clear:
            (out / name).unlink(missing_ok=True)
        return out
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = Path("mdroll-out")
    check_directory_path(base, "output directory")
    _make_directory(base, "output directory", exist_ok=True)
    for _ in range(100):
        out = base / f"{args.command}-{stamp}-{os.getpid()}-{secrets.token_hex(3)}"
        try:
            out.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise UsageError(f"output directory {str(out)!r}: cannot create it ({exc.strerror})") from None
        lock(out, "output directory")
        return out
    raise UsageError(f"output directory: no free name under {str(base)!r}")  # pragma: no cover - 2^24 names a pid


def check_output(args) -> None:
    """``--out`` checked as :func:`output_dir` checks it, making nothing: for a command that makes
    its folder only once it has something to write (a bad input then leaves nothing behind)."""
    if not args.out:
        return
    out = Path(args.out)
    check_directory_path(out, "--out")
    if out.is_dir() and any(entry.name != LOCK for entry in out.iterdir()) and not args.force:
        raise UsageError(f"output directory {str(out)!r} exists and is not empty; use --force to write into it")


def check_directory_path(path: Path, option: str) -> None:
    """Refuse a path that is a file, or lies under one."""
    for ancestor in (path, *path.parents):
        if ancestor.exists() or ancestor.is_symlink():
            if not ancestor.is_dir():
                where = "is a file" if ancestor == path else f"lies under {str(ancestor)!r}, a file"
                raise UsageError(f"{option} {str(path)!r} {where}, not a directory")
            return


def check_file_path(path: Path, option: str) -> None:
    """A file to be written later: its folder must exist and be a writable directory."""
    folder = path.parent
    if path.is_dir():
        raise UsageError(f"{option} {path}: is a directory, expected a file name")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise UsageError(f"{option} {path}: the folder {folder} does not exist or is not writable")


def _make_directory(path: Path, option: str, exist_ok: bool) -> None:
    try:
        path.mkdir(parents=True, exist_ok=exist_ok)
    except OSError as exc:
        raise UsageError(f"{option} {str(path)!r}: cannot create the directory ({exc.strerror})") from None


def lock(out: Path, option: str) -> None:
    """Hold ``out``'s lock file until the command ends (:func:`release_locks`), and check that
    files can be written there; refuse a directory another live mdroll holds."""
    try:
        fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        tempfile.TemporaryFile(dir=out).close()  # a write probe: permissions, read-only file systems
    except OSError as exc:
        raise UsageError(f"{option} {str(out)!r}: cannot write there ({exc.strerror})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        owner = os.read(fd, 32).decode(errors="replace").strip() or "?"
        os.close(fd)
        raise UsageError(f"{option} {str(out)!r} is in use by another running mdroll (pid {owner}); wait for it to "
                         "finish or choose another directory") from None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    _held_locks.append(fd)


def release_locks() -> None:
    """Release every lock this process took (at the end of :func:`mdroll.cli.main`)."""
    while _held_locks:
        os.close(_held_locks.pop())
