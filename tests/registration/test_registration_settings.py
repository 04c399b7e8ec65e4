"""Typed settings of the registration stages: every option checked once (mppf.registration.settings)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.registration.register import register_icp
from mppf.registration.settings import Matching, RegisterOptions
from registration_helpers import asymmetric_surface


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"method": "plain"}, "unknown ICP method"),
        ({"init": "pca"}, "unknown init"),
        ({"init": np.eye(3)}, "4x4"),
        ({"init": np.diag([1.0, 1.0, -1.0, 1.0])}, "not a rigid"),
        ({"robust": "cauchy"}, "robust kernel"),
        ({"trim_fraction": 0.95}, "trim_fraction"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"pin_outline": "yes"}, "pin_outline"),
    ],
)
def test_icp_bad_options(kwargs, words):
    pts = asymmetric_surface(6, 5)
    with pytest.raises(InputError, match=words):
        register_icp(pts, pts, RegisterOptions(**kwargs))

def test_settings_are_frozen_and_give_the_matching():
    settings = RegisterOptions(method="plane", trim_fraction=0.1, robust="huber")
    assert settings.matching == Matching("plane", 0.1, "huber")
    assert settings.tolerances == (1e-3, 1e-5, 1e-9)
    with pytest.raises(AttributeError):
        settings.method = "point"
    with pytest.raises(InputError, match="max_points"):
        RegisterOptions(max_points=50)
    with pytest.raises(InputError, match="tol_translation_mm"):
        RegisterOptions(tol_translation_mm=float("nan"))


def test_register_icp_takes_only_its_options_object():
    pts = asymmetric_surface(6, 5)
    with pytest.raises(InputError, match="RegisterOptions"):
        register_icp(pts, pts, {"method": "plane"})
    assert RegisterOptions().principal_start and not RegisterOptions(init="identity").principal_start
    assert not RegisterOptions(init=np.eye(4)).principal_start
