"""The MDR-against-3-D study (mdroll.studies.mdr3d) against independent references: at a tiny
corrugation both the 3-D solver and the MDR give Hertz's load and the linear force
``k sinc(q a) h`` (closed form); the closed-form filters reduce to the MDR's Si-function filter
(mdroll.roughness.filters) on a corrugation and to their short-wave asymptote on isotropic
roughness; the CNOSSOS-EU A3 values are the shipped table's, read back by numpy; and the study
runs at its test size with its (a) comparison inside first-order theory."""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import special

from mdroll.bem import extruded, self_affine
from mdroll.bem.solver import to_host
from mdroll.roughness import FromCallable
from mdroll.roughness.bands import band_numbers, wavelength_band_edges_q
from mdroll.roughness.filters import mdr_contact_filter
from mdroll.studies import run_study
from mdroll.studies.mdr3d import linear, problems, study

TABLE = Path(problems.__file__).resolve().parents[2] / "roughness" / "railway_tables.tsv"


@pytest.mark.parametrize("name", problems.INDENTERS)
def test_tiny_corrugation_gives_hertz_and_the_linear_force(name, device):
    shape = problems.geometry(name, 0.46, 0.3, 50e3, study.E_STAR)
    mesh = problems.grid(shape, 31, 26, 1.0 / shape.semi_x)
    x = np.arange(mesh.length) * mesh.dx
    amplitude = 1e-4 * shape.approach
    waves = (0.6 / shape.semi_x, 2.5 / shape.semi_x)
    profiles = np.stack([amplitude * f(q * x) for q in waves for f in (np.cos, np.sin)] + [0.0 * x])
    bem, _, converged = problems.bem_forces(shape, mesh, problems.on_device(extruded(profiles, mesh.n), device),
                                            device, 1e-11)
    assert converged.all()
    case = problems.Case("a", name, 0.7, 1e-4, 1.0)

    def springs(modulus, radius, approach):
        """The MDR's own linear force per unit roughness, E* s sum_{|i| <= M} cos(q i s), on its
        springs s = dx / MDR_REFINE apart, M s its reach."""
        step = mesh.dx / problems.MDR_REFINE
        reach = math.floor(math.sqrt(radius * approach) / step)
        return lambda q: modulus * step * math.sin((reach + 0.5) * q * step) / math.sin(0.5 * q * step)

    hertz = lambda q: shape.stiffness * math.sin(q * shape.semi_x) / (q * shape.semi_x)  # noqa: E731
    references = {"bem": (bem, hertz, 2e-3, 0.05),  # its discrete contact edge: O(dx / a)
                  "mdr": (problems.mdr_forces(shape, mesh, case, profiles, "mdr", device),
                          springs(study.E_STAR, shape.radius_x, shape.mdr_approach), 6e-3, 2e-3),
                  "corrected": (problems.mdr_forces(shape, mesh, case, profiles, "corrected", device),
                                springs(shape.corrected_modulus, shape.corrected_radius, shape.corrected_approach),
                                6e-3, 2e-3)}
    for label, (force, linear_force, load_tol, tol) in references.items():
        smooth = force[-1]
        assert np.allclose(smooth, smooth[0], rtol=1e-9)
        assert smooth[0] == pytest.approx(shape.load, rel=load_tol), label
        for j, q in enumerate(waves):
            swing = np.hypot(force[2 * j] - smooth, force[2 * j + 1] - smooth)
            assert swing == pytest.approx(np.full_like(swing, abs(linear_force(q)) * amplitude), rel=tol), (label, q)
    # the corrected MDR's reach is the 3-D a_x to half a spring: its force is the 3-D one to O(s/a)
    assert springs(shape.corrected_modulus, shape.corrected_radius, shape.corrected_approach)(waves[1]) \
        == pytest.approx(hertz(waves[1]), rel=2e-3)


def test_corrected_sphere_matches_the_ellipse_contact():
    shape = problems.geometry("ellipse", 0.46, 0.3, 50e3, study.E_STAR)
    assert shape.semi_x > shape.semi_y
    assert 2.0 * shape.corrected_modulus * shape.semi_x == pytest.approx(shape.stiffness, rel=1e-12)
    assert math.sqrt(shape.corrected_radius * shape.corrected_approach) == pytest.approx(shape.semi_x, rel=1e-12)
    sphere = problems.geometry("sphere", 0.46, 0.3, 50e3, study.E_STAR)
    assert sphere.corrected_radius == pytest.approx(0.46, rel=1e-12)
    assert sphere.stiffness == pytest.approx(2.0 * study.E_STAR * sphere.semi_x, rel=1e-12)


def test_linear_filters_reduce_to_the_mdr_filter_and_the_short_wave_limit():
    a, H = 5e-3, 0.7
    bands = np.arange(20, -1, -1)  # 100 mm to 1 mm
    profile = FromCallable(lambda q: np.abs(q) ** (-2.0 * H - 1.0), kind="profile")
    for model in ("3d", "corrected", "line"):
        closed = linear.contact_filter(model, bands, a, 0.7 * a, H, corrugation=True)
        assert np.allclose(closed, mdr_contact_filter(bands, a, profile), atol=0.02), model
    # the DPRS bed: the band average of (2 J1(q a)/(q a))^2 against the profile's q^(-2H-1), by numpy
    lo, hi = wavelength_band_edges_q(bands)
    dprs = linear.contact_filter("dprs", bands, a, 0.7 * a, H, corrugation=True)
    for value, low, high in zip(dprs, lo, hi):
        q = np.linspace(low, high, 4001)
        weight = q ** (-2.0 * H - 1.0)
        bessel = (2.0 * special.j1(q * a) / (q * a)) ** 2
        assert value == pytest.approx(10.0 * math.log10(np.trapezoid(weight * bessel, q) / np.trapezoid(weight, q)),
                                      abs=0.02)
    short = np.array([-5, 0])  # q a from 28 to 111: sin^2 averages to 1/2 over the lateral integral
    lo, hi = wavelength_band_edges_q(short)
    iso = linear.contact_filter("3d", short, a, a, H)
    for value, low, high in zip(iso, lo, hi):
        q = np.linspace(low, high, 4001)
        weight = q ** (-2.0 * H - 1.0)
        limit = np.trapezoid(weight * (H + 0.5) / ((H + 1.0) * 2.0 * (q * a) ** 2), q) / np.trapezoid(weight, q)
        assert value == pytest.approx(10.0 * math.log10(limit), abs=0.1)


def test_cnossos_values_are_the_shipped_table():
    rows = [line.split("\t") for line in TABLE.read_text().splitlines() if line and not line.startswith("#")]
    table = {name: np.array([float(row[i]) for row in rows[1:]]) for i, name in enumerate(rows[0])}
    forms = study.cnossos_cases(0.3, 0.7)
    assert forms["wavelength_mm"] == table["lambda_mm"].tolist()
    cases = {(c["load_N"], round(c["diameter_m"] * 1e3)): c["A3_dB"] for c in forms["cases"]}
    assert len(cases) == 5
    for column in rows[0][1:6]:
        load, diameter = (float(v) for v in column.removeprefix("A3_").removesuffix("mm").split("kN_"))
        assert cases[(load * 1e3, diameter)] == table[column].tolist()
    bands, values = study.a3_case(50e3, 0.46)
    assert bands.tolist() == band_numbers(table["lambda_mm"]).tolist()
    assert values.tolist() == table["A3_50kN_920mm"].tolist()
    assert study.a3_case(40e3, 0.46) is None


def test_study_at_test_size(device):
    run = run_study("mdr-vs-3d", "test", device=device)
    record = run.record
    assert [f.name for f in run.figures] == ["mdr_vs_3d_bands", "mdr_vs_3d_filter", "mdr_vs_3d_cnossos"]
    sphere = record["measurements"]["runs"]["sphere"]
    assert sphere["bem_converged"]
    corrugation, isotropic = sphere["cases"]
    # (a): the MDR rolls on the profile itself, and first-order theory makes it the 3-D force
    assert corrugation["variants"]["mdr"]["high"]["ratio"] == corrugation["variants"]["line"]["high"]["ratio"]
    assert abs(corrugation["variants"]["mdr"]["high"]["dB"]) < 1.5
    closed = record["measurements"]["closed_forms"]["sphere"]
    bands = corrugation["filter"]["bands"]
    linear_3d = dict(zip(closed["bands"], closed["a"]["3d"]))
    measured = dict(zip(bands, corrugation["filter"]["3d"]))
    mdr = dict(zip(bands, corrugation["filter"]["mdr"]))
    # both filters of a corrugation are sinc^2(q a) to first order; a 48-position record fills the dips
    assert len(bands) >= 4 and all(abs(measured[b] - mdr[b]) < 1.0 for b in bands)
    before_dips = [b for b in bands if linear_3d[b] > -16.0]
    assert len(before_dips) >= 2 and all(abs(measured[b] - linear_3d[b]) < 2.0 for b in before_dips)
    assert isotropic["variants"]["mdr"]["high"]["rel_stderr"] > 0
    assert {c["name"].split()[0] for c in record["claims"]} == {"(a)", "(b)"}
    # the DPRS bed on the same surfaces: its measured filter follows its own closed form, (2 J1(q a)/(q a))^2
    # band-averaged, in the bands clear of J1's zeros (a 48-position record fills the dips), and lies below
    # the 3-D's there
    dprs = dict(zip(bands, corrugation["filter"]["dprs"]))
    linear_dprs = dict(zip(closed["bands"], closed["a"]["dprs"]))
    lo, hi = wavelength_band_edges_q(bands)
    roots = special.jn_zeros(1, 20) / sphere["geometry"]["semi_x"]
    clear = [b for b, low, high in zip(bands, lo, hi) if not np.any((roots >= low) & (roots <= high))]
    assert len(clear) >= 2 and all(abs(dprs[b] - linear_dprs[b]) < 1.5 for b in clear)
    assert all(dprs[b] < measured[b] for b in clear)
    assert corrugation["dprs"]["high"]["dB"] < -1.0 and sphere["dprs_bed"]["stiffness"] == pytest.approx(
        2.0 * 50e3 / sphere["geometry"]["approach"], rel=1e-12)
    assert any(row.startswith("| (a) | sphere | dprs |") for row in record["measurements"]["verdict_table"])
    assert any(row.startswith("| (b) | sphere | dprs |") for row in record["measurements"]["filter_table"])
    cnossos = record["measurements"]["closed_forms"]["cnossos"]["cases"][0]
    assert len(cnossos["dprs_corrugation_dB"]) == len(cnossos["A3_dB"]) == len(cnossos["dprs_isotropic_dB"])


def test_refined_lines_keep_their_spectrum_and_samples(device):
    lines = np.random.default_rng(7).standard_normal((2, 50))
    fine = to_host(problems.refined(lines, 3, device))
    assert np.allclose(fine[:, ::3], lines, rtol=0, atol=1e-13)
    coarse, spectrum = np.fft.rfft(lines), np.fft.rfft(fine)[:, :26] / 3.0
    assert np.allclose(spectrum[:, :25], coarse[:, :25], atol=1e-12)
    assert np.allclose(spectrum[:, 25], 0.5 * coarse[:, 25], atol=1e-12)
    assert np.abs(np.fft.rfft(fine)[:, 26:]).max() < 1e-11


def test_self_affine_is_the_same_surface_on_every_device(device):
    kwargs = dict(H=0.7, q_min=2.0e3, rms=1e-6, seed=3, indices=[0, 5], anisotropy=3.0)
    here = to_host(self_affine((40, 33), 2e-4, device=device, **kwargs))
    reference = self_affine((40, 33), 2e-4, **kwargs)
    assert np.sqrt(np.mean(here**2, axis=(1, 2))) == pytest.approx([1e-6, 1e-6], rel=1e-12)
    assert np.allclose(here, reference, rtol=0, atol=1e-12 * 1e-6)
