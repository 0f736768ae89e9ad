r"""
A rough line from a table of 1/3-octave levels in dB
=====================================================

Rail roughness is specified as 1/3-octave band levels in dB re 1 µm per wavelength band, as in
the EN ISO 3095 limit spectrum (:doc:`/roughness`). :class:`mdroll.roughness.BandLevels` turns
such a table into a PSD (constant inside each band, so that each band holds its level exactly);
:func:`mdroll.rough_lines` makes lines from it with the same reproducible random phases as
always. The round trip, table -> lines -> band levels of the lines' periodograms, returns the
table in every band the line's grid resolves (bands longer than about L/5 hold no grid bin).
``mdroll run --set roughness=bands --set roughness_table=levels.csv`` does the same from the
command line.
"""

import matplotlib.pyplot as plt
import numpy as np

import mdroll
from mdroll.roughness import BandLevels
from mdroll.roughness.bands import nominal, roughness_levels
from mdroll.roughness.tables import iso3095_limit

wavelengths_mm, levels_db = iso3095_limit()  # 2000 mm .. 0.8 mm, dB re 1 µm
spectrum = BandLevels(wavelengths_mm, levels_db, kind="profile", source="EN ISO 3095:2013 limit")

params = mdroll.Params(L=4.0, dx=50e-6)  # 80,000 points: wavelengths from 0.8 m down to 0.1 mm
lines = mdroll.rough_lines(params, seed=6, realizations=4, roughness=spectrum)  # (4, n), metres
print(f"RMS of the lines: {np.sqrt(np.mean(lines**2)) * 1e6:.3g} µm (the table's own level, not h0)")

# %%
# Band levels of what was generated: the lines' mean periodogram (two-sided per rad/m, theory
# section 3) summed over each 1/3-octave band.

B = np.fft.rfft(lines, axis=1) / params.n_points
psd = (params.length / (2 * np.pi) * np.abs(B) ** 2).mean(axis=0)
q = params.dq * np.arange(psd.size)
measured_db, bins = roughness_levels(q, psd, params.dq, spectrum.n)
resolved = bins > 0

fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.5), dpi=100, gridspec_kw={"width_ratios": [3, 2]})
centres = nominal(spectrum.n)
left.semilogx(centres, spectrum.levels_db, "k-", lw=1.2, label="table (EN ISO 3095 limit)")
left.semilogx(centres[resolved], measured_db[resolved], "o", ms=4, color="C1", label="band levels of the lines")
left.invert_xaxis()
left.set_xlabel("wavelength (mm)")
left.set_ylabel("roughness level (dB re 1 µm)")
left.legend(loc="lower left")
x = np.arange(params.n_points) * params.dx
right.plot(x, lines[0] * 1e6, lw=0.5)
right.set_xlabel("x (m)")
right.set_ylabel("h (µm)")
right.set_title("one line")
fig.tight_layout()
plt.show()
