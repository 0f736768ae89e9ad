"""Sphinx configuration of mdroll's documentation site.

Build (warnings are errors): ``python -m sphinx -W -b html docs docs/_build/html``. The pages are
MyST Markdown, the API reference is generated from the docstrings (autosummary + numpydoc), the
CLI reference from the argument parser (sphinx-argparse), and the gallery's examples run during
the build on CPU-sized inputs (sphinx-gallery). MathJax is copied into the build
(sphinx-mathjax-offline), so the site reads offline from the build directory. Each API entry
links to its source (sphinx.ext.linkcode, :func:`linkcode_resolve`), names of numpy, scipy, warp
and dask link to their docs (intersphinx, from the small inventories of docs/_intersphinx/),
and code blocks have a copy button (sphinx-copybutton).
Generated sources (docs/generated, docs/auto_examples) are kept between builds: after renaming
or removing a module or an example, delete them.
"""

import importlib
import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the checkout's mdroll, installed or not
os.environ.setdefault("MPLBACKEND", "agg")

import mdroll  # noqa: E402

project = "mdroll"
author = "the mdroll developers"
copyright = "2026, the mdroll developers"
release = version = mdroll.__version__

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.linkcode",
    "sphinx.ext.mathjax",
    "sphinx_copybutton",
    "sphinxarg.ext",
    "sphinx_gallery.gen_gallery",
    "sphinx-mathjax-offline",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
# the pages are docs/*.md; Markdown in subfolders is data a page includes or links (docs/inverse/)
exclude_patterns = ["_build", "_templates", "_intersphinx", "examples", "*/*.md", "*/**/*.md"]
suppress_warnings = ["myst.header"]

# MyST: $...$ and $$...$$ math, \begin{equation} blocks, heading anchors for links
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence"]
myst_heading_anchors = 3

# API reference: one page per public name, numpydoc sections without its style checks
autosummary_generate = True
templates_path = ["_templates"]
autosummary_imported_members = False
# a package documents what it defines; the names it re-exports are documented at their home
autodoc_default_options = {"members": True, "show-inheritance": False, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_validation_checks = set()
numpydoc_xref_param_type = False

# Links to other projects' docs. The build runs offline (CI reaches PyPI only) with warnings as
# errors, so it cannot download their objects.inv: each project's inventory is a small file in
# docs/_intersphinx/ listing exactly the objects these pages reference, written by
# docs/_intersphinx/make_inventories.py (add an object there and run it to link a new name).
_INVENTORIES = Path(__file__).resolve().parent / "_intersphinx"
intersphinx_mapping = {
    "numpy": ("https://numpy.org/doc/stable/", str(_INVENTORIES / "numpy.inv")),
    "scipy": ("https://docs.scipy.org/doc/scipy/", str(_INVENTORIES / "scipy.inv")),
    "warp": ("https://nvidia.github.io/warp/stable/", str(_INVENTORIES / "warp.inv")),
    "dask": ("https://docs.dask.org/en/stable/", str(_INVENTORIES / "dask.inv")),
    "distributed": ("https://distributed.dask.org/en/stable/", str(_INVENTORIES / "distributed.inv")),
}

# Links from each API entry to its source: MDROLL_SOURCE_URL is the repository's address for
# browsing files (default below), MDROLL_SOURCE_REF the commit or branch (default: the
# checkout's commit, or "main" outside a git checkout).
SOURCE_URL = os.environ.get("MDROLL_SOURCE_URL", "https://github.com/mdroll/mdroll").rstrip("/")


def _source_ref() -> str:
    if "MDROLL_SOURCE_REF" in os.environ:
        return os.environ["MDROLL_SOURCE_REF"]
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "main"


SOURCE_REF = _source_ref()


def linkcode_resolve(domain, info):
    """The address of the source lines of a Python object of mdroll, or None (no link)."""
    if domain != "py" or not info.get("module", "").startswith("mdroll"):
        return None
    try:
        obj = importlib.import_module(info["module"])
        for part in info["fullname"].split("."):
            obj = getattr(obj, part)
        obj = inspect.unwrap(obj)
        path = Path(inspect.getsourcefile(obj)).resolve().relative_to(ROOT)
        lines, first = inspect.getsourcelines(obj)
    except (AttributeError, ImportError, OSError, TypeError, ValueError):
        return None  # data, a Warp kernel without Python source, or a name defined elsewhere
    return f"{SOURCE_URL}/blob/{SOURCE_REF}/{path.as_posix()}#L{first}-L{first + len(lines) - 1}"


# the gallery: every plot_*.py of docs/examples runs during the build (CPU, seconds each)
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "reset_modules": ("matplotlib",),
    "show_memory": False,
    "min_reported_time": 1,
    "write_computation_times": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"mdroll {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "header_links_before_dropdown": 4,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_show_sourcelink = False
# the top-level pages have no section navigation: give their width to the text
html_sidebars = {"*": []}
html_context = {"default_mode": "light"}


# The docstrings write formulas as plain text ("|q|^(-2H-1)", "max |F_tree - F_direct|"), where
# reStructuredText would read "|...|" as a substitution: make "|" literal outside ``literals``,
# roles, literal blocks and tables. Their citations of the theory and performance pages become links,
# and relative module references (":mod:`.report`", a sibling or, in a package, a child) become
# absolute, so that they resolve in autosummary tables on other pages too.
_LITERAL = re.compile(r"(``.*?``)")
_PAGE_CITATION = re.compile(r"(?:docs/)?(physics|performance)\.md((?:'s)? (?:sections? \d+(?:\.\d+)?(?: and \d+(?:\.\d+)?)?|v\d+\w*))?")
_RELATIVE_MODULE = re.compile(r":mod:`\.(\w+(?:\.\w+)*)`")
_ROLE = re.compile(r"(:\w+:`[^`]*`)")  # ":math:`|q|`" keeps its bars
_ROLE_PLURAL = re.compile(r"(:\w+:`[^`]+`)s\b")


def _prose(text: str, package: str) -> str:
    text = "".join(part if _ROLE.fullmatch(part) else part.replace("|", r"\|") for part in _ROLE.split(text))
    text = _PAGE_CITATION.sub(lambda m: f":doc:`{m.group(0)} </{m.group(1)}>`", text)
    text = _RELATIVE_MODULE.sub(lambda m: f":mod:`~{package}.{m.group(1)}`", text)
    return _ROLE_PLURAL.sub(r"\1\\ s", text)  # ":class:`Check`s": a role needs a break after it


def _docstring_prose(app, what, name, obj, options, lines):
    package = name if what == "module" and hasattr(obj, "__path__") else name.rpartition(".")[0]
    if what != "module":  # a function's or class's module is the package its references start from
        package = getattr(obj, "__module__", package).rpartition(".")[0]
    literal_indent = None
    for i, line in enumerate(lines):
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None and (not line.strip() or indent > literal_indent):
            continue
        literal_indent = indent if line.rstrip().endswith("::") else None
        if line.lstrip().startswith(("| ", "+-", "+=")):  # line blocks and grid tables
            continue
        lines[i] = "".join(part if part.startswith("``") else _prose(part, package)
                           for part in _LITERAL.split(line))


def setup(app):
    app.connect("autodoc-process-docstring", _docstring_prose, priority=100)
