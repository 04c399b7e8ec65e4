"""The simulated plate's steel: Hill 48 yield, hardening, layered through-thickness law, plate scatter."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.sim.plate.material import PlateSteel
from mppf.sim.plate.scatter import NO_SCATTER, Scatter, sample_plate
from mppf.sim.plate.through_thickness import LayerLaw, LayerState, layered_response

T_MM = 20.0


def _bend(law, kappas, state=None):
    """Moments (k, 3) along a path of curvature vectors (k, 3) from ``state``; the final state."""
    state = LayerState.virgin(1, len(law.xi)) if state is None else state
    out = []
    for kappa in kappas:
        moment, _, state = layered_response(law, np.atleast_2d(kappa), state, [T_MM], [1.0])
        out.append(moment[0])
    return np.array(out), state


def _closed_form_moment(kappa, yield_mpa, modulus_mpa, plastic_modulus_mpa=0.0):
    """Bilinear moment per width of a beam, N mm/mm: elastic core, linearly hardening skins."""
    k_e = 2.0 * yield_mpa / (modulus_mpa * T_MM)
    if kappa <= k_e:
        return modulus_mpa * T_MM**3 / 12.0 * kappa
    x = k_e / kappa
    core = 0.5 * T_MM * x
    tangent = modulus_mpa * plastic_modulus_mpa / (modulus_mpa + plastic_modulus_mpa) if plastic_modulus_mpa else 0.0
    half = 0.5 * T_MM
    extra = 2.0 * (kappa * (half**3 - core**3) / 3.0 - yield_mpa / modulus_mpa * (half**2 - core**2) / 2.0)
    return yield_mpa * T_MM**2 / 4.0 * (1.0 - x**2 / 3.0) + tangent * extra


def test_hill_is_von_mises_when_isotropic_and_gives_the_transverse_yield():
    iso = PlateSteel(transverse_yield_ratio=1.0)
    assert np.allclose(iso.hill_matrix(), [[1.0, -0.5, 0.0], [-0.5, 1.0, 0.0], [0.0, 0.0, 3.0]])
    for angle in (0.0, 30.0, 90.0):
        steel = PlateSteel(transverse_yield_ratio=1.08, rolling_angle_deg=angle)
        p = steel.hill_matrix()
        a = np.radians(angle)
        for direction, expected in ((a, 1.0), (a + np.pi / 2, 1.08), (a + np.pi / 4, 1.04)):
            c, s = np.cos(direction), np.sin(direction)
            unit = np.array([c * c, s * s, c * s])  # uniaxial stress of 1 MPa along ``direction``
            assert 1.0 / np.sqrt(unit @ p @ unit) == pytest.approx(expected, rel=1e-12)


def test_plate_steel_rejects_bad_values():
    with pytest.raises(InputError, match="Poisson"):
        PlateSteel(poisson=0.5)
    with pytest.raises(InputError, match="transverse yield ratio"):
        PlateSteel(transverse_yield_ratio=2.0)


@pytest.mark.parametrize("hardening_mpa", [0.0, 20000.0])
def test_layer_in_uniaxial_stress_follows_the_bilinear_law(hardening_mpa):
    # strain-driven along u, the transverse strain iterated to zero transverse stress
    steel = PlateSteel(swift_exponent=0.0, linear_hardening_mpa=hardening_mpa, transverse_yield_ratio=1.0)
    law = LayerLaw(steel, layers=2)
    e, sy = steel.youngs_modulus_mpa, steel.yield_stress_mpa
    plastic, alpha = np.zeros((1, 1, 3)), np.zeros((1, 1))
    strain = np.zeros((1, 1, 3))
    for e_uu in np.linspace(0.0, 6.0 * sy / e, 31)[1:]:
        strain[0, 0, 0] = e_uu
        for _ in range(30):
            stress, scale, rank_one, new_plastic, new_alpha = law.stress(strain, plastic, alpha, [1.0])
            if abs(stress[0, 0, 1]) < 1e-9 * abs(stress[0, 0, 0]):
                break
            tangent = (scale[0, 0][None, :] * law.q) @ law.q.T - np.outer(rank_one[0, 0], rank_one[0, 0])
            strain[0, 0, 1] -= stress[0, 0, 1] / tangent[1, 1]
        plastic, alpha = new_plastic, new_alpha
        elastic_limit = sy / e
        hardening_slope = e * hardening_mpa / (e + hardening_mpa)
        expected = e * e_uu if e_uu <= elastic_limit else sy + hardening_slope * (e_uu - elastic_limit)
        assert stress[0, 0, 0] == pytest.approx(expected, rel=1e-9)
        assert alpha[0, 0] == pytest.approx(max(e_uu - expected / e, 0.0), abs=1e-12)


@pytest.mark.parametrize("hardening_mpa", [0.0, 20000.0])
def test_narrow_strip_moment_matches_the_beam_closed_form(hardening_mpa):
    # a narrow strip: M_vv = 0 (kappa_vv iterated); its layers are then nearly, not exactly,
    # in uniaxial stress (elastic core and plastic skins want different transverse
    # curvatures), so the beam law holds to a few tenths of a per cent
    steel = PlateSteel(swift_exponent=0.0, linear_hardening_mpa=hardening_mpa, transverse_yield_ratio=1.0)
    law = LayerLaw(steel)
    state = LayerState.virgin(1, len(law.xi))
    k_e = 2.0 * steel.yield_stress_mpa / (steel.youngs_modulus_mpa * T_MM)
    kappa = np.zeros(3)
    for k_uu in np.linspace(0.0, 4.0 * k_e, 41)[1:]:
        kappa[0] = k_uu
        for _ in range(20):
            moment, tangent, trial = layered_response(law, kappa[None], state, [T_MM], [1.0])
            if abs(moment[0, 1]) < 1e-9 * abs(moment[0, 0]):
                break
            kappa[1] -= moment[0, 1] / tangent.matrix()[0, 1, 1]
        state = trial
        expected = _closed_form_moment(k_uu, steel.yield_stress_mpa, steel.youngs_modulus_mpa, hardening_mpa)
        assert moment[0, 0] == pytest.approx(expected, rel=1e-2 if k_uu > k_e else 1e-9)


@pytest.mark.parametrize("hardening_mpa", [0.0, 20000.0])
def test_plane_strain_layered_moment_matches_the_closed_form(hardening_mpa):
    # plane strain (kappa_vv = 0) at nu -> 1/2: the transverse stress is half the bending
    # stress from first yield on, so sy' = 2 sy / sqrt(3), E' = E / (1 - nu^2), H' = 4 H / 3
    steel = PlateSteel(poisson=0.4999, swift_exponent=0.0, linear_hardening_mpa=hardening_mpa,
                       transverse_yield_ratio=1.0)
    law = LayerLaw(steel)
    sy = 2.0 / np.sqrt(3.0) * steel.yield_stress_mpa
    e_ps = steel.plane_strain_modulus_mpa
    k_e = 2.0 * sy / (e_ps * T_MM)
    path = np.linspace(0.0, 5.0 * k_e, 51)[1:]
    moments, _ = _bend(law, np.column_stack([path, 0 * path, 0 * path]))
    for k, m in zip(path, moments):
        if k >= 2.0 * k_e:
            assert m[0] == pytest.approx(_closed_form_moment(k, sy, e_ps, 4.0 / 3.0 * hardening_mpa), rel=5e-3)
            assert m[1] == pytest.approx(0.5 * m[0], rel=1e-2)


def test_layered_tangent_is_the_derivative_of_the_moments():
    steel = PlateSteel(transverse_yield_ratio=1.1, rolling_angle_deg=30.0, swift_exponent=0.15)
    law = LayerLaw(steel)
    rng = np.random.default_rng(1)
    n = 40
    thickness, factor = np.full(n, T_MM), rng.uniform(0.95, 1.05, n)
    _, _, state = layered_response(law, rng.normal(0, 2e-4, (n, 3)), LayerState.virgin(n), thickness, factor)
    kappa = rng.normal(0, 2e-4, (n, 3))
    _, tangent, _ = layered_response(law, kappa, state, thickness, factor)
    step = 1e-9
    for j in range(3):
        e = np.zeros(3)
        e[j] = step
        plus, _, _ = layered_response(law, kappa + e, state, thickness, factor)
        minus, _, _ = layered_response(law, kappa - e, state, thickness, factor)
        error = np.abs((plus - minus) / (2 * step) - tangent.matrix()[:, :, j]).max(axis=1)
        assert np.all(error <= 1e-7 * np.abs(tangent.matrix()).max(axis=(1, 2)))


def test_springback_is_elastic_and_reverse_bending_yields_again():
    steel = PlateSteel(swift_exponent=0.0, linear_hardening_mpa=1000.0, transverse_yield_ratio=1.0)
    law = LayerLaw(steel)
    k_e = 2.0 * steel.yield_stress_mpa / (steel.plane_strain_modulus_mpa * T_MM)
    path = np.linspace(0.0, 3.0 * k_e, 11)[1:]
    moments, loaded = _bend(law, np.column_stack([path, 0 * path, 0 * path]))
    # unloading to zero moment (springback, plane strain: kappa_f = kappa_i - M / D') is elastic
    sprung = 3.0 * k_e - moments[-1, 0] / (steel.plane_strain_modulus_mpa * T_MM**3 / 12.0)
    moment, unloaded = _bend(law, [[sprung, 0.0, 0.0]], loaded)
    assert moment[0, 0] == pytest.approx(0.0, abs=1e-9 * moments[-1, 0])
    assert np.array_equal(unloaded.alpha, loaded.alpha)
    assert np.allclose(unloaded.plastic_strain, loaded.plastic_strain, rtol=0, atol=1e-15)
    # re-bending up to the old curvature stays elastic; reverse bending yields the skins again
    _, again = _bend(law, [[3.0 * k_e, 0.0, 0.0]], unloaded)
    assert np.array_equal(again.alpha, loaded.alpha)
    _, reversed_ = _bend(law, [[-1.0 * k_e, 0.0, 0.0]], unloaded)
    assert np.all(reversed_.alpha[0, -2:] > loaded.alpha[0, -2:] + 1e-4)


def test_sample_plate_is_seeded_and_scatters_within_its_bounds():
    steel = PlateSteel()
    first = sample_plate(steel, T_MM, Scatter(), seed=7)
    again = sample_plate(steel, T_MM, Scatter(), seed=7)
    uv = np.random.default_rng(0).uniform(-2000, 2000, (500, 2))
    assert first.steel == again.steel and first.thickness_mm == again.thickness_mm
    assert np.array_equal(first.thickness_at(uv), again.thickness_at(uv))
    plates = [sample_plate(steel, T_MM, Scatter(), seed=s) for s in range(200)]
    yields = np.array([p.steel.yield_stress_mpa for p in plates]) / steel.yield_stress_mpa - 1.0
    thick = np.array([p.thickness_mm for p in plates]) / T_MM - 1.0
    assert np.all(np.abs(yields) <= 2 * 0.05 + 1e-12) and 0.03 < yields.std() < 0.06
    assert np.all(np.abs(thick) <= 2 * 0.01 + 1e-12) and len(set(thick)) == 200
    # smooth spatial fields of a few per cent RMS over a large plate
    big = np.random.default_rng(1).uniform(-20000, 20000, (20000, 2))
    field = np.array([np.std(p.yield_factor(big)) for p in plates[:20]])
    assert 0.02 < field.mean() < 0.04
    thickness_field = np.array([np.std(p.thickness_at(big)) / p.thickness_mm for p in plates[:20]])
    assert 0.01 < thickness_field.mean() < 0.02
    nominal = sample_plate(steel, T_MM, NO_SCATTER, seed=3)
    assert np.allclose(nominal.thickness_at(uv), T_MM) and np.allclose(nominal.yield_factor(uv), 1.0)


def test_sample_plate_rejects_bad_values():
    with pytest.raises(InputError, match="thickness"):
        sample_plate(PlateSteel(), 0.0)
    with pytest.raises(InputError, match="yield_field"):
        Scatter(yield_field=0.5)
