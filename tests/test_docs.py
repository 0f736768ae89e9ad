"""The documentation keeps up with the code: every equation and section the code cites is on the
theory page, and every recorded result the pages or the code cite exists (and is cited)."""

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
THEORY = ROOT / "docs" / "physics.md"
RESULTS = ROOT / "benchmarks" / "results"

#: "eq 40", "eq 10-12", "eq 56/58", "eq 36, 48, 49" (and identifiers such as ``eq58_factor``)
EQ_CITATION = re.compile(r"\beqs?\s?(\d+(?:\s*(?:[-/]|,\s*)\s*\d+)*)", re.IGNORECASE)
SECTION_CITATION = re.compile(r"physics\.md'?s?\s+sections?\s+(\d+(?:\.\d+)?)(?:\s*(?:and|,)\s*(\d+(?:\.\d+)?))?")
RESULT_CITATION = re.compile(r"(validation/)?results/([A-Za-z0-9_.{},*-]+/?)")


def _sources(*patterns):
    for pattern in patterns:
        yield from sorted(ROOT.glob(pattern))


def _cited_equations(text: str) -> set[int]:
    numbers = set()
    for match in EQ_CITATION.finditer(text):
        for item in re.split(r"\s*,\s*|\s*/\s*", match.group(1)):
            first, _, last = item.partition("-")
            numbers.update(range(int(first), int(last or first) + 1))
    return numbers


def test_citation_parser_reads_ranges_and_lists():
    text = "eq 10-12 and eq 56/58, eq 36, 48, 49; eq58_factor; eqs 1-2"
    assert _cited_equations(text) == {10, 11, 12, 56, 58, 36, 48, 49, 1, 2}


def test_every_cited_equation_is_numbered_on_the_theory_page():
    theory = THEORY.read_text()
    tagged = {int(n) for n in re.findall(r"\\tag\{(\d+)\}", theory)}
    cited = {}
    for path in _sources("mdroll/**/*.py"):
        for number in _cited_equations(path.read_text()):
            cited.setdefault(number, path.relative_to(ROOT).as_posix())
    assert cited, "no eq N citation found in mdroll/: the pattern is wrong"
    missing = {n: where for n, where in cited.items() if n not in tagged}
    assert not missing, f"cited in mdroll/ but not a \\tag{{N}} equation of docs/physics.md: {missing}"


def test_every_cited_section_exists():
    headings = set(re.findall(r"^#{2,3} (\d+(?:\.\d+)?)\.? ", THEORY.read_text(), re.MULTILINE))
    assert {str(n) for n in range(1, 9)} <= headings, "sections 1-8 of docs/physics.md are cited by number"
    for path in _sources("mdroll/**/*.py"):
        for match in SECTION_CITATION.finditer(path.read_text()):
            for section in filter(None, match.groups()):
                assert section in headings, f"{path.relative_to(ROOT)} cites physics.md section {section}"


PAGES = ("README.md", "docs/*.md")


def _result_citations(*patterns):
    """(citing file, cited path) for every ``results/NAME`` in the files of ``patterns``."""
    for path in _sources(*patterns):
        for match in RESULT_CITATION.finditer(path.read_text()):
            folder = ROOT / "validation" / "results" if match.group(1) else RESULTS
            name = match.group(2).rstrip(".,")
            brace = re.search(r"\{([^}]*)\}", name)  # bench_full_H100.{json,png}
            names = [name[:brace.start()] + part + name[brace.end():] for part in brace.group(1).split(",")] \
                if brace else [name]
            for single in names:
                yield path.relative_to(ROOT).as_posix(), folder / single


def test_every_cited_result_exists():
    citations = [(source, target) for source, target in
                 _result_citations("mdroll/**/*.py", "benchmarks/*.py", "benchmarks/*.sh", *PAGES)
                 if "*" not in target.name]
    assert citations, "no results/ citation found: the pattern is wrong"
    missing = [f"{source}: {target.relative_to(ROOT)}" for source, target in citations if not target.exists()]
    assert not missing, f"cited results that do not exist: {missing}"


def test_every_recorded_result_is_cited_by_a_page():
    text = "".join(path.read_text() for path in _sources(*PAGES))
    expanded = {target.name for _, target in _result_citations(*PAGES)}
    uncited = [p.name for p in sorted(RESULTS.iterdir()) if p.name not in text and p.name not in expanded]
    assert not uncited, f"benchmarks/results/ files no page (README.md, docs/*.md) cites: {uncited}"


@pytest.mark.parametrize("page", [p.relative_to(ROOT).as_posix() for p in _sources(*PAGES)])
def test_pages_link_only_to_files_that_exist(page):
    text = (ROOT / page).read_text()
    base = (ROOT / page).parent
    for target in re.findall(r"\]\(([^)#\s]+)\)", text):
        if "://" in target or target.startswith("mailto:"):
            continue
        assert (base / target).exists(), f"{page} links to {target}, which does not exist"


def test_every_public_name_is_in_the_api_reference():
    import mdroll

    api = (ROOT / "docs" / "api.md").read_text()
    missing = [name for name in mdroll.__all__ if name != "__version__" and f"mdroll.{name}\n" not in api]
    assert not missing, f"public names of mdroll missing from docs/api.md's autosummary: {missing}"


# ------------------------------------------------------------------------ the commands the pages show
#: Pages whose shell blocks (```bash, ```sh, ```console) a newcomer copies.
COMMAND_PAGES = ("README.md", "CONTRIBUTING.md", "docs/*.md", "examples/*/README.md")
SHELL_BLOCK = re.compile(r"^```(?:bash|sh|shell|console)\n(.*?)^```", re.DOTALL | re.MULTILINE)
#: The "command" column of performance.md's table of how to reproduce each figure.
REPRODUCE_ROW = re.compile(r"^\|[^|]*\| `([^`]+)` \| [^|]+ \|$", re.MULTILINE)

#: How each shown command runs in these tests. ("run", COMMAND, CWD): run at a small size in a
#: fresh folder (CWD "tmp") or in a folder of the checkout; ("options", PROGRAM): too large or
#: needing a GPU, a cluster or the user's file here, so its options are checked against
#: ``PROGRAM --help``; ("ci", WHY): run as written by .ci/run (set-up, the suite, the docs build).
SMALL = "--set L=0.05 --realizations 2 --device cpu --no-progress"
COMMANDS = {
    "python -m venv .venv && . .venv/bin/activate && pip install -e '.[test]'": ("ci", "set-up"),
    "pip install -e '.[docs]' && python -m sphinx -W -b html docs docs/_build/html": ("ci", "the docs build"),
    "pip install -e '.[docs]' && python -m sphinx -W -q -b html docs docs/_build/html": ("ci", "the docs build"),
    "python -m pytest": ("ci", "the suite"),
    "lint-imports --no-cache": ("ci", "the contracts"),
    "mdroll run": ("run", f"mdroll run {SMALL}", "tmp"),
    "mdroll run --preset quick": ("run", "mdroll run --preset quick --device cpu --no-progress", "tmp"),
    "mdroll run --workers 2": ("options", "mdroll run"),
    "mdroll run --workers 2 --device cpu": ("run", f"mdroll run --workers 2 {SMALL}", "tmp"),
    "mdroll run --scheduler tcp://host:8786": ("options", "mdroll run"),
    "mdroll run --resume mdroll-out/run-... --workers 2":
        ("run", f"mdroll run --workers 2 {SMALL} --out part && mdroll run --resume part --workers 2 --device cpu"
                " --no-progress",
         "tmp"),
    "dask scheduler": ("options", "dask scheduler"),
    "CUDA_VISIBLE_DEVICES=0 dask worker tcp://head:8786 --nthreads 1": ("options", "dask worker"),
    "CUDA_VISIBLE_DEVICES=1 dask worker tcp://head:8786 --nthreads 1": ("options", "dask worker"),
    "mdroll run --scheduler tcp://head:8786 --realizations 3000": ("options", "mdroll run"),
    "mdroll run --set L=0.5 --realizations 16 --out run1":
        ("run", "mdroll run --set L=0.3 --realizations 8 --seed 4 --out run1 --device cpu --no-progress"
                " && mdroll invert run1 --known m=500 --known R=0.5 --correction none --no-profile --out inv1", "tmp"),
    "mdroll invert run1 --known m=500 --known R=0.5 --out inv1": ("options", "mdroll invert"),
    "mdroll invert accel.csv --frequency-unit Hz --sided one --density Hz --passes 30 --known v0=10 --known m=500 "
    "--known R=0.5 --band 20:20000Hz --free H,q_min,a,h0,E_star,a_jitter,noise": ("options", "mdroll invert"),
    "export PYTHONPATH=/tmp/site:$PWD": ("ci", "shell set-up of the GPU machine"),
    "W=15": ("ci", "shell set-up of the GPU machine"),
    "python3 -m mdroll invert --round-trip --full --lengths 0.5,1 --workers $W --device cuda --no-progress "
    "--out $OUT/a": ("options", "mdroll invert"),
    "python3 -m mdroll invert --round-trip --full --lengths 5 --passes-list 1,10 --workers $W --device cuda "
    "--no-progress --out $OUT/b": ("options", "mdroll invert"),
    "python3 -m mdroll invert --round-trip --full --lengths 5 --passes-list 100,300 --workers $W --device cuda "
    "--no-progress --out $OUT/c": ("options", "mdroll invert"),
    "python3 -m mdroll invert --report $OUT/a/roundtrip.json $OUT/b/roundtrip.json $OUT/c/roundtrip.json":
        ("options", "mdroll invert"),
    "mdroll validate --check mylaw.checks:checks --junit-xml report.xml": ("options", "mdroll validate"),
    "mdroll validate --checks checks.toml": ("options", "mdroll validate"),
    "mdroll validate --installed": ("options", "mdroll validate"),
    "mdroll validate --check lowband_law.checks:checks --junit-xml report.xml":
        ("run", "mdroll validate --check lowband_law.checks:checks --junit-xml {tmp}/report.xml --out {tmp}/val",
         "examples/ci-check"),
    # performance.md, how to reproduce each figure (thesis scale on a GPU)
    "mdroll bench --full --device cuda --out DIR": ("options", "mdroll bench"),
    "python benchmarks/e2e_thesis.py --device cuda:0 --out e2e.json": ("options", "python benchmarks/e2e_thesis.py"),
    "python benchmarks/coupled_thesis.py --out coupled.json": ("options", "python benchmarks/coupled_thesis.py"),
    "python benchmarks/coupled_scaling.py --out coupled_scaling.json":
        ("options", "python benchmarks/coupled_scaling.py"),
    "python benchmarks/coupled_scaling.py --algorithms sweep tree --realizations 75 300 1200 2400 4800 --dx 5e-6 "
    "--warps 4 --out coupled_scaling.json": ("options", "python benchmarks/coupled_scaling.py"),
    "python benchmarks/coupled_scaling.py --algorithms sweep --realizations 300 1200 4800 --dx 5e-6 --warps 1 "
    "--tracks rigid --out coupled_scaling.json": ("options", "python benchmarks/coupled_scaling.py"),
    "python benchmarks/coupled_scaling.py --algorithms sweep --realizations 75 300 600 1200 4800 --dx 5e-6 --warps 4 "
    "--tracks rigid ballasted-soft-pad --helpers 3 0 --out coupled_scaling.json":
        ("options", "python benchmarks/coupled_scaling.py"),
    "python benchmarks/coupled_scaling.py --algorithms sweep --realizations 300 --dx 5e-6 --warps 4 "
    "--tracks ballasted-soft-pad --out coupled_scaling.json": ("options", "python benchmarks/coupled_scaling.py"),
    "python benchmarks/coupled_scaling.py --algorithms sweep --realizations 75 300 600 1200 --dx 5e-6 --warps 4 "
    "--tracks rigid ballasted-soft-pad --helpers 3 0 --out coupled_scaling.json":
        ("options", "python benchmarks/coupled_scaling.py"),
    "python benchmarks/coupled_track.py --out coupled_track.json": ("options", "python benchmarks/coupled_track.py"),
    "ncu --kernel-name regex:coupled --launch-count 1 --section WarpStateStats --section SchedulerStats --section "
    "SourceCounters python benchmarks/coupled_scaling.py --steps-log2 14 --realizations 300 --warps 4 --tracks rigid "
    "--algorithms sweep --repeats 1": ("ci", "Nsight Compute on the GPU machine"),
    "python benchmarks/profile_stages.py --algorithm edge --out profile.json":
        ("options", "python benchmarks/profile_stages.py"),
    "python benchmarks/fft_lengths.py --out fft_lengths.json": ("options", "python benchmarks/fft_lengths.py"),
    "python benchmarks/sweep_stream_tuning.py --out sweep_stream.json":
        ("options", "python benchmarks/sweep_stream_tuning.py"),
    "python benchmarks/sweep_exponents.py --device cpu --out exponents.json":
        ("options", "python benchmarks/sweep_exponents.py"),
    "python benchmarks/tree_tuning.py --device cuda:0 --out tree_tuning.json":
        ("options", "python benchmarks/tree_tuning.py"),
    "python benchmarks/kernel_resources.py --match tree": ("options", "python benchmarks/kernel_resources.py"),
    "python benchmarks/scaleout.py --device cuda:0 --out scaleout.json": ("options", "python benchmarks/scaleout.py"),
    "python benchmarks/unit_latency.py --device cuda:0 --out unit_latency.json":
        ("options", "python benchmarks/unit_latency.py"),
    "python benchmarks/cpu_full_run.py --repeats 3 --out cpu_full_run.json":
        ("options", "python benchmarks/cpu_full_run.py"),
    "OUT=DIR bash benchmarks/gpu_session.sh tests": ("ci", "the GPU machine's session script"),
    # track.md: the moving load over discrete supports
    "mdroll run --mode coupled --set track=ballasted-soft-pad --set track.parametric=true": ("options", "mdroll run"),
    # track.md: the track alone
    "mdroll track receptance --set track=ballasted-soft-pad --position midspan --out rec":
        ("run", "mdroll track receptance --set track=ballasted-soft-pad --position midspan --points 20 --out rec",
         "tmp"),
    "mdroll track decay --set track=ballasted-stiff-pad --set track.pad_loss=0.3 --out dec":
        ("run", "mdroll track decay --set track=ballasted-stiff-pad --set track.pad_loss=0.3 --out dec", "tmp"),
    "python benchmarks/track_chain.py --out track_chain.json": ("options", "python benchmarks/track_chain.py"),
    # track.md: the track study (quick: minutes of CPU; full: GPU) and the inverse fit on a track
    "mdroll roughness check --only track --device cpu --out track-quick": ("options", "mdroll roughness check"),
    "mdroll roughness check --full --only track --device cuda --out track-full": ("options", "mdroll roughness check"),
    "python docs/track/make_study_tables.py benchmarks/results/track_study_quick.json":
        ("run", "python docs/track/make_study_tables.py benchmarks/results/track_study_quick.json", "."),
    "mdroll invert run-on-track --known m=500 --known R=0.5 --known E=2.1e11 --known nu=0.3 --band 300:20000Hz "
    "--correction none": ("options", "mdroll invert"),
    "mdroll invert accel.csv --frequency-unit Hz --sided one --density Hz --passes 30 --known v0=10 --known m=500 "
    "--known R=0.5 --set track=ballasted-soft-pad": ("options", "mdroll invert"),
    # mdr-vs-3d.md: the study's quick run (minutes on a CPU) and its full run (a GPU)
    "mdroll study mdr-vs-3d --quick --device cpu --out docs/mdr-vs-3d/quick --force": ("options", "mdroll study"),
    "python3 -m mdroll study mdr-vs-3d --full --device cuda --out $OUT/mdr3d --no-progress":
        ("options", "mdroll study"),
}


def _shown_commands() -> dict[str, str]:
    """{command: page} for every command of a shell block of the pages (continuation lines
    joined, prompts and comments dropped) and of performance.md's reproduce table."""
    shown = {}
    for path in _sources(*COMMAND_PAGES):
        page = path.relative_to(ROOT).as_posix()
        text = path.read_text()
        for block in SHELL_BLOCK.findall(text):
            for line in re.sub(r"\\\n\s*", " ", block).splitlines():
                command = " ".join(re.sub(r"\s+#.*$", "", line.removeprefix("$ ")).split())
                if command:
                    shown.setdefault(command, page)
        if page == "docs/performance.md":
            for command in REPRODUCE_ROW.findall(text):
                shown.setdefault(command, page)
    return shown


def test_every_shown_command_is_run_or_checked():
    shown = _shown_commands()
    assert "mdroll run" in shown and len(shown) > 20, "the shell blocks were not found: the pattern is wrong"
    missing = {command: page for command, page in shown.items() if command not in COMMANDS}
    assert not missing, f"commands shown in the docs that tests/test_docs.py does not run or check: {missing}"
    stale = [command for command in COMMANDS if command not in shown]
    assert not stale, f"commands of tests/test_docs.py that no page shows any more: {stale}"


@pytest.fixture(scope="module")
def console(tmp_path_factory):
    """A PATH whose ``mdroll`` is the console script of pyproject.toml on this checkout's mdroll
    (as ``pip install -e .`` makes it: the working directory is not on its path)."""
    import sys
    import tomllib

    target = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]["mdroll"]
    module, _, function = target.partition(":")
    bin_dir = tmp_path_factory.mktemp("bin")
    script = bin_dir / "mdroll"
    script.write_text(f"#!{sys.executable}\nimport sys\nfrom {module} import {function}\n\n"
                      f"if __name__ == '__main__':\n    sys.exit({function}())\n")
    script.chmod(0o755)
    python = bin_dir / "python"
    python.symlink_to(sys.executable)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", PYTHONPATH=os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]),
               MPLBACKEND="agg", MDROLL_CACHE_DIR=str(tmp_path_factory.mktemp("cache")))
    return env


def _run(command: str, cwd: Path, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("shown", [c for c, how in COMMANDS.items() if how[0] == "run"])
def test_shown_command_runs_at_a_small_size(shown, console, tmp_path):
    _, command, cwd = COMMANDS[shown]
    where = tmp_path if cwd == "tmp" else ROOT / cwd
    proc = _run(command.format(tmp=tmp_path), where, console)
    assert proc.returncode == 0, f"{command!r} (shown as {shown!r}) failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"


@pytest.fixture(scope="module")
def usage(console):
    """The options a program takes: a script's ``add_argument`` calls (read, not run: the GPU
    scripts import CuPy), or a command's ``--help``, asked once a program."""
    known = {}

    def options(program: str) -> str:
        if program not in known:
            script = re.fullmatch(r"python (benchmarks/\w+\.py)", program)
            if script:
                known[program] = " ".join(re.findall(r"add_argument\(([^)]*)", (ROOT / script[1]).read_text()))
            else:
                if shutil.which(program.split()[0], path=console["PATH"]) is None:
                    pytest.skip(f"{program.split()[0]} is not installed here (the test extra installs it)")
                proc = _run(f"{program} --help", ROOT, console)
                assert proc.returncode == 0, f"{program} --help failed:\n{proc.stderr[-2000:]}"
                known[program] = proc.stdout
        return known[program]

    return options


@pytest.mark.parametrize("shown", [c for c, how in COMMANDS.items() if how[0] == "options"])
def test_shown_command_uses_existing_options(shown, usage):
    program = COMMANDS[shown][1]
    text = usage(program)
    options = set(re.findall(r"(?<![\w-])--[a-z][\w-]*", shown)) - {"--help"}
    unknown = sorted(o for o in options if not re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", text))
    assert not unknown, f"{shown!r} uses options that {program} does not have: {unknown}"
