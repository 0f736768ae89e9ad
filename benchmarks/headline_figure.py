"""The README's headline figure and the docs' spectrum figures: the thesis defaults with the
default estimator (Hann window) beside the thesis's own setup (open, no window), both with the
unresolved bins shaded.

    python benchmarks/headline_figure.py --device cuda:0 --out headline.json           # thesis scale
    python benchmarks/headline_figure.py --device cpu --length 0.2 --realizations 8 --out small.json

Writes ``docs/accel_psd_default.png`` and ``docs/accel_psd_thesis.png`` (the acceleration),
``docs/force_psd_default.png`` and ``docs/force_psd_thesis.png`` (the force), the two estimators
side by side in ``docs/accel_psd_estimators.png``, and the record (``--out``: parameters, the
estimator of each figure, the low band's ratio to the forced response, the unresolved counts,
the environment).
"""

import argparse
import json
from pathlib import Path

import numpy as np

from mdroll import Params, plotting, run_ensemble
from mdroll.devices import resolve_device
from mdroll.ensemble.resolution import estimator_name
from mdroll.files import atomic_write
from mdroll.physics import acceleration_transfer
from mdroll.provenance import environment

DOCS = Path(__file__).resolve().parent.parent / "docs"
ESTIMATORS = {"default": True, "thesis": False}


def low_band_ratio(result) -> float:
    """The acceleration PSD over the forced response |A/F|^2 C_F, summed on [0.1, 0.3] omega_0."""
    p = result.params
    band = (result.omega >= 0.1 * p.omega_0) & (result.omega <= 0.3 * p.omega_0)
    forced = acceleration_transfer(result.omega[band], p.k_contact, p.m) * result.force_psd[band]
    return float(result.accel_psd[band].sum() / forced.sum())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--out", default="headline.json")
    parser.add_argument("--length", type=float, default=5.24288, help="L (m); default: 2^20 springs at dx = 5 um")
    parser.add_argument("--realizations", type=int, default=300)
    args = parser.parse_args()
    device = resolve_device(args.device)
    p = Params(L=args.length)
    record = {"environment": environment(device), "params": p.as_dict(), "realizations": args.realizations,
              "figures": {}}
    results = {}
    for name, window in ESTIMATORS.items():
        result = run_ensemble(p, realizations=args.realizations, window=window, device=device, progress=False)
        results[name] = result
        for quantity in ("accel", "force"):
            with atomic_write(DOCS / f"{quantity}_psd_{name}.png") as file:
                plotting.plot_psd(result, quantity, file)
        flags = result.resolution
        record["figures"][name] = {"estimator": estimator_name(window), "boundary": result.boundary,
                                   "accel_over_forced_0.1_0.3_omega0": low_band_ratio(result),
                                   "unresolved_bins": {q: int(flags.mask(q).sum()) for q in ("accel", "force")},
                                   "bins": int(result.q.size)}
        print(name, json.dumps(record["figures"][name]))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(14, 5), dpi=120, sharey=True, layout="constrained")
    for ax, (name, result) in zip(axes, results.items()):
        plotting.plot_psd(result, "accel", ax=ax)
        ax.set_title(f"{estimator_name(result.window)}: low band / forced response "
                     f"{record['figures'][name]['accel_over_forced_0.1_0.3_omega0']:.3g}", fontsize=9)
    with atomic_write(DOCS / "accel_psd_estimators.png") as file:
        fig.savefig(file)
    plt.close(fig)
    with atomic_write(Path(args.out), "w") as file:
        json.dump(record, file, indent=1, default=lambda v: v.tolist() if isinstance(v, np.ndarray) else str(v))


if __name__ == "__main__":
    main()
