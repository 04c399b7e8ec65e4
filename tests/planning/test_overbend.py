"""Springback over-bend of the planner's first guess: the principal arcs swapped for over-bent ones."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError
from mppf.model.material import Material
from mppf.forming.springback import loaded_curvature
from mppf.planning.overbend import overbend
from plan_helpers import CylinderSurface

T = 20.0


def test_overbend_turns_a_cylinder_into_the_loaded_cylinder():
    steel = Material(206000.0, 0.3, 235.0)
    radius = 5000.0
    bent = overbend(CylinderSurface(radius), T, steel, half_size_mm=900.0)
    k_loaded = float(loaded_curvature(1.0 / radius, T, steel))
    v = np.linspace(-800, 800, 9)
    u = np.full_like(v, 300.0)
    z, zu, zv, zuu, zuv, zvv = bent.derivatives(u, v)
    r_loaded = 1.0 / k_loaded
    np.testing.assert_allclose(z, r_loaded - np.sqrt(r_loaded**2 - v**2), atol=1e-9)
    np.testing.assert_allclose(zv, v / np.sqrt(r_loaded**2 - v**2), atol=1e-12)
    np.testing.assert_allclose(zvv, r_loaded**2 / (r_loaded**2 - v**2) ** 1.5, rtol=1e-9)
    np.testing.assert_allclose([zu, zuu, zuv], 0.0, atol=1e-15)


def test_overbend_refuses_a_radius_too_small_for_the_plate():
    steel = Material(206000.0, 0.3, 235.0)
    with pytest.raises(GeometryError, match="too small"):
        overbend(CylinderSurface(1200.0), T, steel, half_size_mm=1100.0)
