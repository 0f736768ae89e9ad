"""The full default run (``mdroll run``: 300 x 10^6 points, decoupled, the default algorithm) on
the CPU, timed from outside: wall, user and system CPU time, page faults and memory from
``/usr/bin/time -v``, the load average before and after (the machine may be shared), and the
run's own stage times (summary.json). Each repeat is a fresh process.

    python benchmarks/cpu_full_run.py --repeats 3 --out benchmarks/results/cpu_full_default_run_sweep_2threads.json

docs/performance.md (CPU) records the numbers and what they point at.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mdroll.provenance import environment

#: What ``/usr/bin/time -v`` prints, and the key each becomes.
TIME_FIELDS = {
    "Elapsed (wall clock) time (h:mm:ss or m:ss)": "wall_s",
    "User time (seconds)": "cpu_user_s",
    "System time (seconds)": "cpu_system_s",
    "Percent of CPU this job got": "percent_of_cpu_this_job_got",
    "Maximum resident set size (kbytes)": "max_resident_GiB",
    "Minor (reclaiming a frame) page faults": "minor_page_faults",
}


def seconds(text: str) -> float:
    """``h:mm:ss`` or ``m:ss.ss`` -> seconds."""
    value = 0.0
    for part in text.split(":"):
        value = 60 * value + float(part)
    return value


def parse_time(report: str) -> dict:
    """The fields of :data:`TIME_FIELDS` from a ``/usr/bin/time -v`` report."""
    out = {}
    for line in report.splitlines():
        name, _, value = line.strip().rpartition(": ")
        key = TIME_FIELDS.get(name)
        if key == "wall_s":
            out[key] = round(seconds(value), 2)
        elif key == "percent_of_cpu_this_job_got":
            out[key] = int(value.rstrip("%"))
        elif key == "max_resident_GiB":
            out[key] = round(int(value) * 1024 / 2**30, 2)
        elif key is not None:
            out[key] = float(value) if "." in value else int(value)
    return out


def load_average() -> list[float]:
    return [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]]


def one_run(out: Path) -> tuple[dict, dict]:
    """One ``mdroll run`` under ``/usr/bin/time -v``: its record and its summary.json."""
    command = ["/usr/bin/time", "-v", sys.executable, "-m", "mdroll", "run", "--no-progress", "--device", "cpu",
               "--out", str(out), "--force"]
    before = load_average()
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    run = parse_time(done.stderr)
    run["load_average_before"], run["load_average_after"] = before, load_average()
    summary = json.loads((out / "summary.json").read_text())
    run["timings_s"] = {name: round(value, 3) for name, value in summary["timings_s"].items()}
    run["when"] = time.strftime("%H:%M UTC", time.gmtime())
    return run, summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", required=True, help="the JSON record to write")
    args = parser.parse_args()
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeats):
            run, summary = one_run(Path(tmp) / "run")
            runs.append(run)
            print(json.dumps(run), flush=True)
    commit = subprocess.run(["git", "describe", "--always", "--dirty", "--abbrev=40"], capture_output=True, text=True)
    record = {
        "what": f"the full default run ({summary['n_real']} x {summary['derived']['n_points']['value']} points; "
                f"{summary['algorithm']}, {summary['mode']}, {summary['boundary']}) on a CPU machine without a GPU, "
                f"{os.cpu_count()} cores, realizations in parts taken by one Python thread a core (run_ensemble threads=None)",
        "command": "python benchmarks/cpu_full_run.py (each run: python -m mdroll run --no-progress --device cpu "
                   "--out DIR --force, under /usr/bin/time -v)",
        "commit": commit.stdout.strip(),
        "note": "the machine may be shared: the load average (1, 5, 15 min, /proc/loadavg) before and after each run; "
                "user + system CPU time is the number least changed by other jobs. /usr/bin/time's percent is of one "
                "core. Stage times (summary.json) are means over the threads (they overlap); the merge of the parts' "
                "moments, on the main thread, counts in 'spectra'.",
        "batch": summary["batch"],
        "steps": summary["steps"],
        "algorithm": summary["algorithm"],
        "force_rms_N": summary["force_rms_N"],
        "force_mean_N": summary["force_mean_N"],
        "environment": {**environment("cpu"), "cores": os.cpu_count(),
                        "host_memory_GiB": round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30)},
        "runs": runs,
    }
    Path(args.out).write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
