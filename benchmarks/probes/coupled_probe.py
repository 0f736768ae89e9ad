"""Coupled dynamics alone at thesis scale (300 x 2^20, one batch, warm), for a given source tree:
``python benchmarks/probes/coupled_probe.py SRC edge tree`` with SRC a directory holding an
``mdroll`` package (the checkout, or an older commit's ``git archive``), to compare versions."""
import sys, time
sys.path.insert(0, sys.argv[1])
import mdroll
from mdroll import Params, run_ensemble
from mdroll.devices import synchronize
from mdroll.ensemble.force import prepare_lines
from mdroll.ensemble.lines import rough_lines
from mdroll.ensemble.pipeline import coupled_series, H_BOUND_SIGMAS
from mdroll.devices import to_warp
print(mdroll.__file__)
p = Params(L=5.24288, n_real=300)
dev = "cuda:0"
for alg in sys.argv[2:]:
    lines = to_warp(rough_lines(p, 0, 300, device=dev), dev)
    prep = prepare_lines(lines, p, alg, "open", p.d0, dev, h_max=H_BOUND_SIGMAS * p.h0)
    coupled_series(prep, p, alg, dev); synchronize(dev)
    t = time.perf_counter(); coupled_series(prep, p, alg, dev); synchronize(dev)
    print(alg, "steps", prep.steps, "coupled_series", round(time.perf_counter() - t, 3), "s", flush=True)
