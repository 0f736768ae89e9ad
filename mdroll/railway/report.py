"""Railway-acoustics outputs of a run: 1/3-octave band spectra beside the narrow-band PSDs.

Roughness level L_r (dB re 1 um) of the run's roughness spectrum against wavelength; force level
(dB re 1 N, and re 1 uN, the reference of ISO 1683: :data:`UN_OVER_N_DB` more) and acceleration
level (dB re 1e-6 m/s^2, ISO 1683) of the ensemble against frequency (Hz), and for a coupled run
on a track the wheel's and the rail's velocity levels at the contact (dB re 1 nm/s, ISO 1683;
:mod:`mdroll.ensemble.vibration`),
band-integrated by the rule of :mod:`mdroll.roughness.bands` (sum over the bins inside a band of
the one-sided PSD times the bin width). Written into summary.json (``"bands"``), bands.csv and
bands.png (both axes: wavelength and frequency f = v0 / lambda).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from .. import roughness
from ..ensemble.vibration import VIBRATION
from ..experiments import Figure, write_figure
from ..files import atomic_write
from ..params import Params
from ..roughness import bands

#: dB re 1 uN minus dB re 1 N: 20 log10(1 N / 1 uN).
UN_OVER_N_DB = 120.0


def band_spectra(result, spectrum=None) -> dict:
    """The band spectra of an ensemble result (``result.q``, ``force_psd``, ``accel_psd``,
    ``params``) with the roughness of ``spectrum`` (default: the one ``result.params`` names, as
    generated: :func:`mdroll.roughness.grid_psd`). JSON-ready: per band its nominal label, exact centre,
    the other axis at v0, level (dB; NaN where the band holds no bin) and bin count."""
    p: Params = result.params
    spectrum = roughness.from_params(p) if spectrum is None else spectrum
    grid = roughness.grid_psd(p, spectrum)
    q_line = p.dq * np.arange(grid.size)
    top = float(np.max(q_line[grid > 0]))
    n_wave = bands.wavelength_bands_of_grid(p.dq, top)
    L_r, count_r = bands.roughness_levels(q_line, grid, p.dq, n_wave)
    dq = float(result.q[1] - result.q[0])
    n_freq = bands.frequency_bands_of_grid(dq, float(result.q[-1]), p.v0)
    L_F, count_f = bands.frequency_levels(result.q, result.force_psd, dq, n_freq, p.v0, "force")
    L_a, _ = bands.frequency_levels(result.q, result.accel_psd, dq, n_freq, p.v0, "acceleration")
    lam = bands.band_centres(n_wave) * 1e-3
    f = bands.band_centres(n_freq)

    def clean(values):
        return [None if not np.isfinite(v) else float(v) for v in values]

    vibration = {f"L_v_{name}_dB": clean(bands.frequency_levels(result.q, psd, dq, n_freq, p.v0, "velocity")[0])
                 for name, (psd, _) in result.vibration().items()}
    return {
        "rule": "band mean square = sum over grid bins q_lo <= q_k < q_hi of 2 C(q_k) dq (C two-sided); "
                "IEC 61260 base-10 bands, centre 10^(n/10) mm or Hz, edges centre 10^(-+1/20)",
        "v0": p.v0,
        "roughness": {"reference": "1 um", "wavelength_nominal_mm": bands.nominal(n_wave).tolist(),
                      "wavelength_m": lam.tolist(), "frequency_Hz": (p.v0 / lam).tolist(), "L_r_dB": clean(L_r),
                      "bins": count_r.tolist()},
        "force_acceleration": {"reference": "L_F_dB: 1 N; L_F_uN_dB: 1 uN (ISO 1683); L_a_dB: 1e-6 m/s^2 (ISO 1683)",
                               "frequency_nominal_Hz": bands.nominal(n_freq).tolist(),
                               "frequency_Hz": f.tolist(), "wavelength_m": (p.v0 / f).tolist(), "L_F_dB": clean(L_F),
                               "L_F_uN_dB": clean(L_F + UN_OVER_N_DB), "L_a_dB": clean(L_a), "bins": count_f.tolist()},
        **({"vibration": {"reference": "1 nm/s (ISO 1683)", "frequency_nominal_Hz": bands.nominal(n_freq).tolist(),
                          "frequency_Hz": f.tolist(), "wavelength_m": (p.v0 / f).tolist(), **vibration,
                          "bins": count_f.tolist()}} if vibration else {}),
    }


def bands_csv(spectra: dict) -> str:
    """One CSV of the tables: quantity (roughness, force, acceleration and, on a track,
    wheel_velocity and rail_velocity), nominal band, unit, level (dB), reference, wavelength (m),
    frequency (Hz), bins."""
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(["quantity", "band_nominal", "band_unit", "level_dB", "reference", "wavelength_m", "frequency_Hz",
                     "bins"])
    r = spectra["roughness"]
    for row in zip(r["wavelength_nominal_mm"], r["L_r_dB"], r["wavelength_m"], r["frequency_Hz"], r["bins"]):
        writer.writerow(["roughness", row[0], "mm", row[1], "1 um", row[2], row[3], row[4]])
    fa = spectra["force_acceleration"]
    for name, key, ref in (("force", "L_F_dB", "1 N"), ("force", "L_F_uN_dB", "1 uN"),
                           ("acceleration", "L_a_dB", "1e-6 m/s^2")):
        for row in zip(fa["frequency_nominal_Hz"], fa[key], fa["wavelength_m"], fa["frequency_Hz"], fa["bins"]):
            writer.writerow([name, row[0], "Hz", row[1], ref, row[2], row[3], row[4]])
    vib = spectra.get("vibration", {})
    for name in VIBRATION:
        for row in zip(vib.get("frequency_nominal_Hz", ()), vib.get(f"L_v_{name}_dB", ()), vib.get("wavelength_m", ()),
                       vib.get("frequency_Hz", ()), vib.get("bins", ())):
            writer.writerow([name, row[0], "Hz", row[1], "1 nm/s", row[2], row[3], row[4]])
    return out.getvalue()


def band_figure(spectra: dict) -> Figure:
    """bands.png: L_r against wavelength (frequency at v0 on top), L_F and L_a against frequency
    (wavelength at v0 on top); on a track also the wheel's and the rail's velocity levels."""
    v0 = spectra["v0"]
    vib = spectra.get("vibration")

    def draw(fig):
        ax_r, ax_f, *ax_v = fig.subplots(3 if vib else 2, 1)
        r = spectra["roughness"]
        lam_mm = np.array(r["wavelength_m"]) * 1e3
        ax_r.semilogx(lam_mm, np.array(r["L_r_dB"], dtype=float), "o-")
        ax_r.invert_xaxis()
        ax_r.set_xlabel("wavelength (mm)")
        ax_r.set_ylabel("$L_r$ (dB re 1 \u00b5m)")
        ax_r.set_title("roughness level, 1/3-octave bands", fontsize=10)
        ax_r.grid(True, which="both", alpha=0.3)
        top = ax_r.secondary_xaxis("top", functions=(lambda x: v0 / (np.maximum(x, 1e-12) * 1e-3),
                                                      lambda f: v0 / np.maximum(f, 1e-12) * 1e3))
        top.set_xlabel(f"frequency at v0 = {v0:g} m/s (Hz)")
        fa = spectra["force_acceleration"]
        f = np.array(fa["frequency_Hz"])
        ax_f.semilogx(f, np.array(fa["L_F_dB"], dtype=float), "o-",
                      label=f"force $L_F$ (dB re 1 N; re 1 \u00b5N, ISO 1683: +{UN_OVER_N_DB:g} dB, right axis)")
        ax_f.semilogx(f, np.array(fa["L_a_dB"], dtype=float), "s-",
                      label="acceleration $L_a$ (dB re 1 \u00b5m/s$^2$, ISO 1683)")
        ax_f.set_xlabel("frequency (Hz)")
        ax_f.set_ylabel("level (dB re 1 N; re 1 \u00b5m/s$^2$)")
        ax_f.set_title("force and acceleration levels, 1/3-octave bands", fontsize=10)
        right = ax_f.secondary_yaxis("right", functions=(lambda x: x + UN_OVER_N_DB, lambda x: x - UN_OVER_N_DB))
        right.set_ylabel("force level (dB re 1 \u00b5N, ISO 1683)")
        ax_f.legend(fontsize=8)
        ax_f.grid(True, which="both", alpha=0.3)
        top = ax_f.secondary_xaxis("top", functions=(lambda f: v0 / np.maximum(f, 1e-12) * 1e3,
                                                      lambda x: v0 / (np.maximum(x, 1e-12) * 1e-3)))
        top.set_xlabel(f"wavelength at v0 = {v0:g} m/s (mm)")
        for ax in ax_v:
            for name in VIBRATION:
                if f"L_v_{name}_dB" in vib:
                    ax.semilogx(vib["frequency_Hz"], np.array(vib[f"L_v_{name}_dB"], dtype=float), "o-",
                                label=name.replace("_", " ") + " at the contact")
            ax.set_xlabel("frequency (Hz)")
            ax.set_ylabel("$L_v$ (dB re 1 nm/s)")
            ax.set_title("vibration velocity levels, 1/3-octave bands (ISO 1683)", fontsize=10)
            ax.legend(fontsize=8)
            ax.grid(True, which="both", alpha=0.3)

    return Figure("bands", "1/3-octave band levels of the roughness, force and acceleration", draw,
                  size=(8, 11 if vib else 8), dpi=110)


def write_band_outputs(result, out, summary: dict | None = None) -> dict:
    """bands.csv and bands.png into ``out``; the band spectra added to ``summary`` under "bands"
    (when given) and returned."""
    out = Path(out)
    spectra = band_spectra(result)
    text = bands_csv(spectra)
    with atomic_write(out / "bands.csv", "w") as file:
        file.write(text)
    write_figure(band_figure(spectra), out / "bands.png")
    if summary is not None:
        summary["bands"] = spectra
    return spectra
