"""The documentation keeps up with the code: every equation and section the code cites is on the
theory page, and every recorded result the pages or the code cite exists (and is cited)."""

import re
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
