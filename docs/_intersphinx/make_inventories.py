"""Write the small intersphinx inventories of docs/_intersphinx/ (run from anywhere:
``python docs/_intersphinx/make_inventories.py``).

The site links to numpy, scipy, warp and dask, but the docs build runs without network access
(CI reaches PyPI only) and with warnings as errors, so it cannot fetch those projects'
``objects.inv``. Each project gets instead a small inventory here listing exactly the objects
the pages and docstrings reference, with their addresses in that project's online docs; conf.py
points ``intersphinx_mapping`` at these files. To link a new object, add it to ``OBJECTS``
and run this script (it checks each file by reading it back with Sphinx's own reader).
"""

from __future__ import annotations

import zlib
from pathlib import Path

from sphinx.util.inventory import InventoryFile

HERE = Path(__file__).resolve().parent

#: project -> (its docs' base address, version, [(name, domain:role, page#anchor)]); "$" in a page
#: stands for the name, as in Sphinx's own inventories.
OBJECTS = {
    "numpy": ("https://numpy.org/doc/stable/", "stable", [
        ("numpy.ndarray", "py:class", "reference/generated/numpy.ndarray.html#$"),
        ("numpy.savez", "py:function", "reference/generated/numpy.savez.html#$"),
        ("numpy.load", "py:function", "reference/generated/numpy.load.html#$"),
    ]),
    "scipy": ("https://docs.scipy.org/doc/scipy/", "stable", [
        ("scipy.integrate.quad_vec", "py:function", "reference/generated/scipy.integrate.quad_vec.html#$"),
        ("scipy.optimize.minimize", "py:function", "reference/generated/scipy.optimize.minimize.html#$"),
    ]),
    "warp": ("https://nvidia.github.io/warp/stable/", "stable", [
        ("warp.array", "py:class", "user_guide/runtime.html#arrays"),
        ("warp.launch", "py:function", "user_guide/runtime.html#kernels"),
    ]),
    "dask": ("https://docs.dask.org/en/stable/", "stable", [
        ("dask.array", "py:module", "array.html"),
    ]),
    "distributed": ("https://distributed.dask.org/en/stable/", "stable", [
        ("distributed.Client", "py:class", "api.html#$"),
        ("distributed.LocalCluster", "py:class", "api.html#$"),
    ]),
}


def inventory_bytes(project: str, version: str, objects) -> bytes:
    """An ``objects.inv`` of format version 2 holding ``objects``."""
    header = (f"# Sphinx inventory version 2\n# Project: {project}\n# Version: {version}\n"
              "# The remainder of this file is compressed using zlib.\n").encode()
    body = "".join(f"{name} {role} 1 {page} -\n" for name, role, page in objects).encode()
    return header + zlib.compress(body)


def main() -> None:
    for project, (base, version, objects) in OBJECTS.items():
        path = HERE / f"{project}.inv"
        path.write_bytes(inventory_bytes(project, version, objects))
        read = InventoryFile.loads(path.read_bytes(), uri=base)
        by_role = getattr(read, "data", read)  # Sphinx 9 wraps the {role: {name: item}} dict of Sphinx 8
        names = {name for items in by_role.values() for name in items}
        assert names == {name for name, _, _ in objects}, f"{path}: read back {sorted(names)}"
        print(f"wrote {path.name}: {len(objects)} objects")


if __name__ == "__main__":
    main()
