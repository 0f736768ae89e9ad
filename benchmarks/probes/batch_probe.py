"""Does ``default_batch`` hand the pools' memory back during warm thesis-scale runs? Three runs per
algorithm in one process, with the free device memory, CuPy's pool and each release timed.
(H200, 2026-11-21: no release; edge ran 45 ms after the tree and direct runs, 32 ms alone.)"""
import time, sys
import cupy
from mdroll import Params, run_ensemble
from mdroll.ensemble import pipeline
from mdroll.devices import warp
wp = warp()
p = Params(L=5.24288, n_real=300)
calls = []
orig = pipeline._release_pools
def traced(device):
    t = time.perf_counter(); orig(device); wp.synchronize_device(device); calls.append(time.perf_counter() - t)
pipeline._release_pools = traced
for alg in ("tree", "direct", "edge"):
    for i in range(3):
        free = wp.get_device("cuda:0").free_memory
        pool = cupy.get_default_memory_pool()
        t = time.perf_counter(); run_ensemble(p, algorithm=alg, device="cuda:0", progress=False); wp.synchronize_device("cuda:0")
        print(alg, i, f"free {free/2**30:.1f} GiB cupy pool total {pool.total_bytes()/2**30:.1f} free {pool.free_bytes()/2**30:.1f}",
              f"run {1e3*(time.perf_counter()-t):.1f} ms releases {len(calls)} last {1e3*calls[-1] if calls else 0:.1f} ms", flush=True)
