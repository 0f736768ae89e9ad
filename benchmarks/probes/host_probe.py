"""Costs around the stages of a thesis-scale run (CuPy only): the flat prefix scan with and
without CuPy's CUB accelerator, and bringing K = 518,401 bins of results to the host (separate
gets, one stacked get, into page-locked memory), against the host arithmetic on them.

    python benchmarks/probes/host_probe.py --out host.json
"""
import argparse
import json
import math
import statistics
import time

import cupy
import cupyx
import numpy as np

from cupy._core import _accelerator

K = 518_401
R, N = 300, 2**20 + 2 * 5_000


def median_ms(fn, repeats=7):
    fn()
    times = []
    for _ in range(repeats):
        cupy.cuda.Device().synchronize()
        t = time.perf_counter()
        fn()
        cupy.cuda.Device().synchronize()
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="host.json")
    args = parser.parse_args()
    record = {"cupy": cupy.__version__, "device": cupy.cuda.runtime.getDeviceProperties(0)["name"].decode(),
              "accelerators_default": [int(a) for a in _accelerator.get_routine_accelerators()]}
    lines = cupy.random.standard_normal(R * N)
    out = cupy.empty(R * N + 1)
    for name, acc in (("default", None), ("cub", [_accelerator.ACCELERATOR_CUB]), ("none", [])):
        if acc is not None:
            _accelerator.set_routine_accelerators(acc)
        record[f"cumsum_{name}_ms"] = median_ms(lambda: cupy.cumsum(lines, out=out[1:]))
    record["cub_device_scan_ms"] = median_ms(lambda: cupy.cuda.cub.device_scan(lines, cupy.cuda.cub.CUPY_CUB_CUMSUM))
    record["copy_ms"] = median_ms(lambda: out[1:].__setitem__(slice(None), lines))
    del lines, out

    rows = cupy.random.random((4, K))
    record["four_gets_ms"] = median_ms(lambda: [rows[i].get() for i in range(4)])
    record["stacked_get_ms"] = median_ms(lambda: rows.get())
    pinned = cupyx.empty_pinned((4, K))
    record["get_into_pinned_ms"] = median_ms(lambda: rows.get(out=pinned))
    record["get_into_pinned_and_copy_ms"] = median_ms(lambda: (rows.get(out=pinned), pinned.copy()))
    record["new_pinned_and_get_ms"] = median_ms(lambda: rows.get(out=cupyx.empty_pinned((4, K))))
    host = rows.get()
    record["host_stderr_ms"] = median_ms(lambda: np.sqrt(host[1] / 299 / 300))
    record["host_wavenumbers_ms"] = median_ms(lambda: 2.0 * math.pi * np.arange(K) / (2 * (K - 1) * 5e-6) * 10.0)
    record["device_stderr_ms"] = median_ms(lambda: cupy.sqrt(rows[1] / 299 / 300))
    for k, v in record.items():
        print(k, v if not isinstance(v, float) else round(v, 3), flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
