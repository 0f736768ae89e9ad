"""Writes ``tests/data/reference_run.npz``: small ensembles whose spectra a refactoring must keep.

The stored spectra were produced by this script on the CPU; ``tests/test_reference_run.py`` runs
the same cases and compares to rounding. Regenerate only for a change that is meant to alter the
spectra, and say so in the commit body.

    python tests/make_reference_run.py
"""

from pathlib import Path

import numpy as np

from mdroll import Params, run_ensemble

#: name -> (Params fields, run_ensemble keywords). Small lines, every exact algorithm, both modes.
CASES = {
    f"{mode}_{algorithm}_{boundary}": (
        {"L": 0.04, "dx": 20e-6},
        {"algorithm": algorithm, "mode": mode, "boundary": boundary, "window": window},
    )
    for mode, algorithm, boundary, window in [
        ("decoupled", "direct", "open", False),
        ("decoupled", "tree", "open", False),
        ("decoupled", "sweep", "periodic", True),
        ("decoupled", "edge", "open", False),
        ("coupled", "sweep", "open", False),
        ("coupled", "tree", "periodic", False),
    ]
}
SEED = 11
REALIZATIONS = 3
PATH = Path(__file__).parent / "data" / "reference_run.npz"


def run_case(name: str, device: str = "cpu"):
    fields, options = CASES[name]
    return run_ensemble(Params(**fields), seed=SEED, realizations=REALIZATIONS, device=device,
                        progress=False, **options)


def main() -> None:
    arrays = {}
    for name in CASES:
        result = run_case(name)
        arrays[f"{name}/force_psd"] = result.force_psd
        arrays[f"{name}/accel_psd"] = result.accel_psd
    np.savez_compressed(PATH, **arrays)


if __name__ == "__main__":
    main()
