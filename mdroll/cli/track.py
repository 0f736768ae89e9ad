"""``mdroll track receptance | decay``: the track alone, in the frequency domain (docs/track.md).

``receptance`` writes the rail's vertical point receptance where the wheel stands
(``receptance.csv``: ``frequency_Hz,re_m_per_N,im_m_per_N``, log-spaced frequencies) and its plot;
``decay`` writes the decay rate in the 1/3-octave bands of the EN ISO 3095 limit, the limit and
the verdict per band (``decay.csv``) and its plot. The track comes from ``--set track=PRESET`` and
``--set track.KEY=VALUE`` (:meth:`mdroll.track.Track.from_settings`; default the continuous
:class:`~mdroll.track.Track`). Every output is written whole or not at all.
"""

from __future__ import annotations

import csv
import io

import numpy as np

from ..errors import UsageError
from ..files import atomic_write
from .common import Parser, output_dir, output_options

#: Bounds of the receptance's frequencies (Hz) and of its number of points.
F_LIMITS = (0.01, 100_000.0)
POINTS_LIMITS = (2, 20_000)


def add_parser(sub) -> None:
    p = sub.add_parser("track", help="the track alone: point receptance, decay rates against EN ISO 3095 "
                       "(docs/track.md)")
    tasks = p.add_subparsers(dest="task", required=True, parser_class=Parser)
    rec = tasks.add_parser("receptance", help="the rail's vertical point receptance where the wheel stands: "
                           "receptance.csv (frequency_Hz,re_m_per_N,im_m_per_N) and receptance.png")
    _track_options(rec)
    rec.add_argument("--position", choices=("sleeper", "midspan"), default="sleeper",
                     help="where the wheel stands on a discretely supported rail (default sleeper)")
    rec.add_argument("--f-min", type=float, default=5.0, help="lowest frequency (Hz, default 5)")
    rec.add_argument("--f-max", type=float, default=10_000.0, help="highest frequency (Hz, default 10000)")
    rec.add_argument("--points", type=int, default=400, help="log-spaced frequencies (default 400)")
    output_options(rec)
    dec = tasks.add_parser("decay", help="decay rates in the 1/3-octave bands 250 Hz - 5 kHz against the "
                           "EN ISO 3095 vertical limit: decay.csv and decay.png")
    _track_options(dec)
    output_options(dec)


def _track_options(p) -> None:
    p.add_argument("--set", action="append", metavar="track.KEY=VALUE",
                   help="track=PRESET or track.KEY=VALUE (repeatable; keys and presets in docs/track.md)")


def _track(args):
    from ..track import Track

    items = args.set or []
    for item in items:
        key = item.partition("=")[0].strip()
        if key != "track" and not key.startswith("track."):
            raise UsageError(f"--set {item}: mdroll track takes track=PRESET and track.KEY=VALUE only")
    track = Track.from_settings(items)
    if track.support == "rigid":
        raise UsageError("track.support = 'rigid': an immovable rail has no receptance or decay rate to write; "
                         "choose continuous or discrete (or a preset other than rigid)")
    return track


def _frequencies(args) -> np.ndarray:
    lo, hi = F_LIMITS
    for name, value in (("--f-min", args.f_min), ("--f-max", args.f_max)):
        if not (np.isfinite(value) and lo <= value <= hi):
            raise UsageError(f"{name} {value:g}: a frequency must lie in [{lo:g}, {hi:g}] Hz")
    if args.f_min >= args.f_max:
        raise UsageError(f"--f-min {args.f_min:g} must be below --f-max {args.f_max:g}")
    if not POINTS_LIMITS[0] <= args.points <= POINTS_LIMITS[1]:
        raise UsageError(f"--points {args.points}: the number of frequencies must lie in "
                         f"[{POINTS_LIMITS[0]}, {POINTS_LIMITS[1]}]")
    return np.geomspace(args.f_min, args.f_max, args.points)


def _write_csv(path, header, rows) -> None:
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    with atomic_write(path, "w") as file:
        file.write(text.getvalue())


def receptance_table(track, f, position):
    """(header, rows) of receptance.csv: frequency (Hz) and the receptance's real and imaginary
    parts (m/N), 10 significant digits."""
    from ..track import receptance

    alpha = receptance(track, f, position)
    rows = [(f"{fi:.10g}", f"{a.real:.10g}", f"{a.imag:.10g}") for fi, a in zip(f, alpha)]
    return ("frequency_Hz", "re_m_per_N", "im_m_per_N"), rows, alpha


def decay_table(track):
    """(header, rows, values) of decay.csv: nominal 1/3-octave band (Hz), the decay rate at the
    band's exact centre (dB/m), the EN ISO 3095 vertical limit (dB/m) and ``pass`` where the
    rate reaches it, else ``fail``."""
    from ..track import decay_rate, iso3095_decay_limit

    nominal, limit = iso3095_decay_limit()
    exact = 1000.0 * 10.0 ** (np.round(10 * np.log10(nominal / 1000.0)) / 10)
    rate = decay_rate(track, exact)
    rows = [(f"{n:g}", f"{r:.4g}", f"{lim:g}", "pass" if r >= lim else "fail")
            for n, r, lim in zip(nominal, rate, limit)]
    return ("band_Hz", "decay_dB_per_m", "iso3095_limit_dB_per_m", "pass"), rows, (nominal, rate, limit)


def _figure(name, caption, draw):
    from ..experiments import Figure

    return Figure(name, caption, draw, size=(7.0, 4.5), dpi=110)


def execute(args) -> int:
    from ..experiments import write_figure

    track = _track(args)
    if args.task == "receptance":
        f = _frequencies(args)
        out = output_dir(args)
        header, rows, alpha = receptance_table(track, f, args.position)
        _write_csv(out / "receptance.csv", header, rows)

        def draw(fig):
            top, bottom = fig.subplots(2, 1, sharex=True)
            top.loglog(f, np.abs(alpha))
            top.set_ylabel("|receptance| (m/N)")
            bottom.semilogx(f, np.degrees(np.angle(alpha)))
            bottom.set_ylabel("phase (degrees)")
            bottom.set_xlabel("frequency (Hz)")
            for ax in (top, bottom):
                ax.grid(True, which="both", alpha=0.3)
            top.set_title(f"rail point receptance, {track.support} support, wheel at the {args.position}")

        write_figure(_figure("receptance", "The rail's point receptance", draw), out / "receptance.png")
        return 0
    out = output_dir(args)
    header, rows, (bands, rate, limit) = decay_table(track)
    _write_csv(out / "decay.csv", header, rows)

    def draw(fig):
        ax = fig.subplots()
        ax.semilogx(bands, rate, "o-", label="decay rate")
        ax.semilogx(bands, limit, "k--", label="EN ISO 3095 vertical limit")
        ax.set_xlabel("1/3-octave band (Hz)")
        ax.set_ylabel("decay rate (dB/m)")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()

    write_figure(_figure("decay", "Track decay rates and the EN ISO 3095 limit", draw), out / "decay.png")
    return 0
