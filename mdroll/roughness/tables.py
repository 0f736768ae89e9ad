"""Railway reference tables by 1/3-octave wavelength band, read from the package's data file
``railway_tables.tsv`` (shipped with mdroll; its header states the sources, as below).

Sources:

* :data:`ISO3095_SOURCE`: the EN ISO 3095:2013 rail roughness limit spectrum, dB re 1 um, as
  transcribed in the open implementation NoiseModelling (Universite Gustave Eiffel),
  ``noisemodelling-emission/.../railway/RailwayEmissionCnossos.json``; also Commission Directive
  (EU) 2015/996, Annex II, Table G-1.
* :data:`A3_SOURCE`: the CNOSSOS-EU contact filter A3 (dB) of the railway source model,
  Directive (EU) 2015/996 Annex II, entries EU3-EU7 of the same NoiseModelling file. Caveats
  (kept from the data file): the transcription labels the loads "wheel load"; its 360 mm column
  equals the 100 kN / 920 mm column shifted by three bands (possibly a transcription artefact).

The file is tab-separated: ``#`` comment lines (the sources), a header ``lambda_mm``,
``A3_<load>kN_<diameter>mm`` per contact-filter case, ``iso3095_dB``, then one row per band,
longest wavelength first.
"""

from __future__ import annotations

import functools
import re
from importlib import resources

import numpy as np

ISO3095_SOURCE = ("EN ISO 3095:2013 limit spectrum via NoiseModelling RailwayEmissionCnossos.json "
                  "(also Directive (EU) 2015/996 Annex II Table G-1)")
A3_SOURCE = ("CNOSSOS-EU contact filter A3, Directive (EU) 2015/996 Annex II, via NoiseModelling "
             "RailwayEmissionCnossos.json entries EU3-EU7")

#: The data file, a resource of this package.
TABLE_FILE = "railway_tables.tsv"
_A3_COLUMN = re.compile(r"A3_(\d+(?:\.\d+)?)kN_(\d+(?:\.\d+)?)mm")


@functools.cache
def _columns() -> dict[str, np.ndarray]:
    text = resources.files(__package__).joinpath(TABLE_FILE).read_text(encoding="utf-8")
    rows = [line.split("\t") for line in text.splitlines() if line.strip() and not line.startswith("#")]
    header, values = rows[0], np.array([[float(v) for v in row] for row in rows[1:]], dtype=np.float64)
    return {name: values[:, i] for i, name in enumerate(header)}


def iso3095_limit() -> tuple[np.ndarray, np.ndarray]:
    """(wavelength mm, level dB re 1 um) of the EN ISO 3095:2013 limit spectrum, longest first."""
    columns = _columns()
    return columns["lambda_mm"].copy(), columns["iso3095_dB"].copy()


def cnossos_a3() -> tuple[np.ndarray, dict]:
    """(wavelength mm, {(load N, diameter m): A3 dB}) of the CNOSSOS-EU contact filter."""
    columns = _columns()
    cases = {}
    for name, column in columns.items():
        match = _A3_COLUMN.fullmatch(name)
        if match:
            cases[(float(match.group(1)) * 1000.0, float(match.group(2)) / 1000.0)] = column.copy()
    return columns["lambda_mm"].copy(), cases
