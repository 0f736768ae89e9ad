"""The command line, ``mdroll COMMAND ...`` (also ``python -m mdroll ...``): one module per command,
each with ``add_parser(sub)`` and ``execute(args) -> exit code``, and :mod:`.common` for what they
share.

A user's error (:class:`~mdroll.errors.MdrollError`, a bad option included) prints one line on
stderr and exits with code 2; any other exception is a bug and shows its traceback. Stderr holds
mdroll's own lines only: the libraries' Python warnings (matplotlib's on a plot's empty or
non-positive data, numpy's) are silenced unless ``python -W`` or ``PYTHONWARNINGS`` asks for them;
what a user must know is an ``mdroll: warning:`` line.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import signal
import sys
import warnings

from ..errors import MdrollError, NonFiniteError
from . import bench, invert, merge, params, roughness, run, study, track, validate
from .common import Parser, release_locks

#: The commands in the order ``mdroll --help`` lists them.
COMMANDS = {"params": params, "run": run, "validate": validate, "merge": merge, "invert": invert, "bench": bench,
            "roughness": roughness, "study": study, "track": track}


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command."""
    parser = Parser(prog="mdroll", description="MDR rolling contact on rough rails: ensembles, forces, spectra.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in COMMANDS.values():
        command.add_parser(sub)
    return parser


#: OS errors that the machine's state or a path causes, not mdroll (a full disk, a read-only or
#: forbidden folder, a name too long, a directory where a file is meant): one line naming the path.
_ENVIRONMENT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS, errno.ENAMETOOLONG,
                       errno.EISDIR, errno.ENOTDIR, errno.EFBIG, errno.ELOOP}


class _Terminated(KeyboardInterrupt):
    """SIGTERM (a scheduler stopping the job), raised so that it unwinds like Ctrl-C: temporary
    files are removed, the lock released, the last checkpoint kept."""


def _raise_terminated(signum, frame):
    raise _Terminated


def _error(text: str) -> int:
    """The one line a user's error prints; exit code 2."""
    print(f"mdroll: error: {text}", file=sys.stderr)
    return 2


def _kept(command) -> str:
    """What an OS error while writing leaves: outputs are atomic, so the file is its old version or absent."""
    kept = "that file was not written (every output is written whole or not at all: any earlier version is kept"
    if command == "run":
        kept += "; the checkpoint of the finished batches too, for mdroll run --resume DIR"
    return kept + ")"


def main(argv=None) -> int:
    """Run ``mdroll`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    previous, command = None, None
    with contextlib.suppress(ValueError):  # only the main thread may set a handler
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        args = build_parser().parse_args(argv)
        command = args.command
        with warnings.catch_warnings():
            if not sys.warnoptions:  # python -W or PYTHONWARNINGS shows them
                warnings.simplefilter("ignore")
            code = COMMANDS[args.command].execute(args)
        sys.stdout.flush()  # here, so that a closed pipe is met inside the handlers below
        return code
    except NonFiniteError as exc:  # a force or spectrum not finite: realization and stage named
        return _error(f"{exc}; the parameters give non-finite numbers")
    except MdrollError as exc:
        return _error(str(exc))
    except MemoryError:
        return _error("out of memory; lower --batch or --memory-limit, or L (more than the free memory was taken "
                      "while the run went on)")
    except BrokenPipeError:  # the reader left (mdroll params | head -2): nothing more to say
        with contextlib.suppress(OSError, ValueError, AttributeError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a tool killed by the closed pipe reports
    except OSError as exc:  # after BrokenPipeError, an OSError too
        if exc.errno not in _ENVIRONMENT_ERRNOS:
            raise
        return _error((f"{exc.filename}: " if exc.filename else "") + f"{exc.strerror}; {_kept(command)}")
    except _Terminated:
        after = "; continue with mdroll run --resume DIR" if command == "run" else ""
        print(f"mdroll: terminated{after}", file=sys.stderr)
        return 143  # 128 + SIGTERM
    except KeyboardInterrupt:
        print("mdroll: interrupted", file=sys.stderr)
        return 130
    finally:
        release_locks()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
