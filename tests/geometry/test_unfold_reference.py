"""The flat plates of real designs stay those unfolded before the triangulation's peeling was made faster.

``data/unfold_reference.npz`` holds the flat points (n, 2) mm of bundled real plates (a hull patch
and the 9 m KCS stern plate, whose projections are triangulated and peeled), unfolded by the code
as it was before (``python tests/geometry/test_unfold_reference.py`` writes it again: only on
purpose, when the unfolding is meant to change).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold

EXAMPLES = Path(__file__).resolve().parents[2] / "mppf" / "examples"
REFERENCE = Path(__file__).resolve().parent / "data" / "unfold_reference.npz"
PLATES = {"P2": EXAMPLES / "hull" / "P2_bow_flare.csv", "K3": EXAMPLES / "hull" / "K3_stern_saddle.csv",
          "kcs_stern": EXAMPLES / "long" / "kcs_stern_bilge_9000x2400.csv"}
TOLERANCE_MM = 1e-6


def unfolded(name: str) -> dict[str, np.ndarray]:
    """The flat points (n, 2) mm and the triangle count of a bundled plate."""
    design = read_points(PLATES[name])
    unfolding = unfold(design.points, design.faces)
    return {f"{name}_flat": unfolding.flat[:, :2], f"{name}_triangles": np.array(len(unfolding.faces))}


@pytest.mark.parametrize("name", list(PLATES))
def test_the_flat_plate_matches_the_reference(name):
    reference = np.load(REFERENCE)
    got = unfolded(name)
    expected = reference[f"{name}_flat"]
    assert got[f"{name}_flat"].shape == expected.shape
    assert np.max(np.abs(got[f"{name}_flat"] - expected)) < TOLERANCE_MM
    assert int(got[f"{name}_triangles"]) == int(reference[f"{name}_triangles"])


if __name__ == "__main__":
    REFERENCE.parent.mkdir(exist_ok=True)
    np.savez_compressed(REFERENCE, **{k: v for name in PLATES for k, v in unfolded(name).items()})
    print(f"wrote {REFERENCE}")
