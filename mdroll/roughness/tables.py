"""Railway reference tables by 1/3-octave wavelength band, transcribed from the project's
``shared/data/railway_tables.tsv`` (tests/test_roughness.py compares them with it when present).

Sources, as that file states them:

* :data:`ISO3095_SOURCE`: the EN ISO 3095:2013 rail roughness limit spectrum, dB re 1 um, as
  transcribed in the open implementation NoiseModelling (Universite Gustave Eiffel),
  ``noisemodelling-emission/.../railway/RailwayEmissionCnossos.json``; also Commission Directive
  (EU) 2015/996, Annex II, Table G-1.
* :data:`A3_SOURCE`: the CNOSSOS-EU contact filter A3 (dB) of the railway source model,
  Directive (EU) 2015/996 Annex II, entries EU3-EU7 of the same NoiseModelling file. Caveats
  (kept from the data file): the transcription labels the loads "wheel load"; its 360 mm column
  equals the 100 kN / 920 mm column shifted by three bands (possibly a transcription artefact).
"""

from __future__ import annotations

import numpy as np

ISO3095_SOURCE = ("EN ISO 3095:2013 limit spectrum via NoiseModelling RailwayEmissionCnossos.json "
                  "(also Directive (EU) 2015/996 Annex II Table G-1)")
A3_SOURCE = ("CNOSSOS-EU contact filter A3, Directive (EU) 2015/996 Annex II, via NoiseModelling "
             "RailwayEmissionCnossos.json entries EU3-EU7")

#: Nominal 1/3-octave band centre wavelengths (mm), longest first.
WAVELENGTHS_MM = (2000, 1600, 1250, 1000, 800, 630, 500, 400, 315, 250, 200, 160, 125, 100, 80, 63, 50, 40, 31.5, 25, 20, 16, 12.5, 10, 8, 6.3, 5, 4, 3.15, 2.5, 2, 1.6, 1.25, 1, 0.8,)

#: EN ISO 3095:2013 limit, dB re 1 um, per band of :data:`WAVELENGTHS_MM`.
ISO3095_DB = (17.1, 17.1, 17.1, 17.1, 17.1, 17.1, 17.1, 17.1, 15.0, 13.0, 11.0, 9.0, 7.0, 4.9, 2.9, 0.9, -1.1, -3.2, -5.0, -5.6, -6.2, -6.8, -7.4, -8.0, -8.6, -9.2, -9.8, -10.4, -11.0, -11.6, -12.2, -12.8, -13.4, -14.0, -14.0,)

#: CNOSSOS-EU A3 (dB) per (wheel load N, wheel diameter m), per band of :data:`WAVELENGTHS_MM`.
A3_DB = {
    (50000.0, 0.36): (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.1, -0.2, -0.3, -0.6, -1.0, -1.8, -3.2, -5.4, -8.7, -12.2, -16.7, -17.7, -17.8, -20.7, -22.1, -22.8, -24.0, -24.5, -24.7, -27.0, -27.8),
    (50000.0, 0.68): (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.1, -0.2, -0.3, -0.7, -1.2, -2.0, -4.1, -6.0, -9.2, -13.8, -17.2, -17.7, -18.6, -21.5, -22.3, -23.1, -24.4, -24.5, -25.0, -28.0, -28.8, -29.6),
    (25000.0, 0.92): (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.1, -0.3, -0.5, -1.1, -1.8, -3.3, -5.3, -7.9, -12.8, -16.8, -17.7, -18.2, -20.5, -22.0, -22.8, -24.2, -24.5, -25.0, -27.4, -28.2, -29.0),
    (50000.0, 0.92): (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.1, -0.1, -0.3, -0.6, -1.1, -1.3, -3.5, -5.3, -8.0, -12.0, -16.8, -17.7, -18.0, -21.5, -21.8, -22.8, -24.0, -24.5, -25.0, -27.3, -28.1, -28.9, -29.7),
    (100000.0, 0.92): (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.1, -0.2, -0.3, -0.6, -1.0, -1.8, -3.2, -5.4, -8.7, -12.2, -16.7, -17.7, -17.8, -20.7, -22.1, -22.8, -24.0, -24.5, -24.7, -27.0, -27.8, -28.6, -29.4, -30.2),
}


def iso3095_limit() -> tuple[np.ndarray, np.ndarray]:
    """(wavelength mm, level dB re 1 um) of the EN ISO 3095:2013 limit spectrum."""
    return np.array(WAVELENGTHS_MM, dtype=np.float64), np.array(ISO3095_DB, dtype=np.float64)


def cnossos_a3() -> tuple[np.ndarray, dict]:
    """(wavelength mm, {(load N, diameter m): A3 dB}) of the CNOSSOS-EU contact filter."""
    return np.array(WAVELENGTHS_MM, dtype=np.float64), {k: np.array(v, dtype=np.float64) for k, v in A3_DB.items()}
