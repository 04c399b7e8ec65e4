"""The strain picture of an unfolding (mppf.report.strain)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.geometry.mesh import boundary_edges
from mppf.geometry.unfold import unfold
from mppf.report.strain import plot_strain, strain_figure


@pytest.fixture(scope="module")
def cap():
    """A spherical cap 1.2 x 0.8 m, radius 3 m: a little strain when laid flat."""
    u, v = np.meshgrid(np.linspace(-600, 600, 25), np.linspace(-400, 400, 17))
    w = 3000.0 - np.sqrt(3000.0**2 - u**2 - v**2)
    return unfold(np.column_stack([u.ravel(), v.ravel(), w.ravel()]), strain_limit_pct=0.01)


def test_strain_picture_draws_the_outline_and_the_limit(cap, tmp_path):
    fig = strain_figure(cap)
    ax = fig.axes[0]
    assert len(ax.collections[-1].get_segments()) == len(boundary_edges(cap.faces))  # the outline
    assert "EXCEEDS" in ax.get_title()  # the 0.01 % limit
    path = plot_strain(cap, tmp_path / "cap.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unwritable_picture_is_an_input_error(cap, tmp_path):
    with pytest.raises(InputError, match="cannot write the strain picture"):
        plot_strain(cap, tmp_path / "no" / "such" / "cap.png")
