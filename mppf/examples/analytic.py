"""Analytic full-size plates with exact answers: a long cylinder and a twisted plate.

Each generator returns the design mid-surface and its flat plate as paired (n, 3) point arrays
(same order, as :func:`mppf.geometry.unfold.unfold` gives them), in mm, so tests and benchmarks
can plan plates of any size without files. ``python -m mppf.examples.analytic OUT_DIR`` writes the
bundled CSV files of ``mppf/examples/long/`` (``long_cylinder_*.csv``, ``twisted_*.csv`` and the
manifest ``plates.csv`` for ``mppf batch --manifest``).
"""

from __future__ import annotations

import numpy as np

from mppf.core.transform import apply_tf, make_tf


def _grid(length_mm: float, width_mm: float, spacing_mm: float):
    nx = int(np.ceil(length_mm / spacing_mm)) + 1
    ny = int(np.ceil(width_mm / spacing_mm)) + 1
    s, y = np.meshgrid(np.linspace(-length_mm / 2, length_mm / 2, nx), np.linspace(-width_mm / 2, width_mm / 2, ny))
    return s.ravel(), y.ravel()


def hull_pose(angle_deg: float = 17.0, shift_mm=(41000.0, -3200.0, 1500.0)) -> np.ndarray:
    """(4, 4): a rigid placement standing in for the hull coordinates of a design."""
    a, b = np.radians(angle_deg), np.radians(angle_deg / 3.0)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return make_tf(rz @ rx, shift_mm)


def cylinder_plate(length_mm: float = 7500.0, width_mm: float = 2400.0, radius_mm: float = 20000.0, *,
                   spacing_mm: float = 50.0, tf_world_plate=None):
    """A cylindrical plate bent along its length, with its exact development.

    The arc length s along the bend and the straight coordinate y across it are the flat plate's
    coordinates; the design is x = R sin(s / R), z = R (1 - cos(s / R)) (axis along y).

    Parameters
    ----------
    length_mm, width_mm : float
        Developed (flat) size: the arc length along the bend and the width along the axis.
    radius_mm : float
        Radius of the mid-surface.
    spacing_mm : float
        Point spacing on the flat.
    tf_world_plate : (4, 4) float, optional
        Where the design lies (default :func:`hull_pose`).

    Returns
    -------
    design, flat : (n, 3) float, mm
    """
    s, y = _grid(length_mm, width_mm, spacing_mm)
    local = np.column_stack([radius_mm * np.sin(s / radius_mm), y, radius_mm * (1.0 - np.cos(s / radius_mm))])
    design = apply_tf(hull_pose() if tf_world_plate is None else tf_world_plate, local)
    return design, np.column_stack([s, y, np.zeros_like(s)])


def cylinder_height_mm(x_mm, radius_mm: float):
    """Exact mid-surface height of :func:`cylinder_plate` above its lowest line at x (its own frame)."""
    x = np.asarray(x_mm, dtype=float)
    return radius_mm - np.sqrt(radius_mm ** 2 - x ** 2)


def twisted_plate(length_mm: float = 7500.0, width_mm: float = 2400.0, twist_mm: float = 60.0, *,
                  spacing_mm: float = 50.0, tf_world_plate=None):
    """A twisted plate z = 4 c x y / (L W): its corners rise and fall by c = ``twist_mm``.

    Not developable: its flat is unfolded by :func:`mppf.geometry.unfold.unfold` (strain
    of the order (c / W)^2, below 0.1 % for the default). The exact surface is its formula.

    Returns
    -------
    design : (n, 3) float, mm
        In the hull pose (default :func:`hull_pose`).
    local : (n, 3) float, mm
        The same points in the plate's own frame (z = 4 c x y / (L W)).
    """
    x, y = _grid(length_mm, width_mm, spacing_mm)
    local = np.column_stack([x, y, 4.0 * twist_mm * x * y / (length_mm * width_mm)])
    return apply_tf(hull_pose() if tf_world_plate is None else tf_world_plate, local), local


def main(argv=None) -> None:
    """Write the bundled analytic example plates as CSV files into a folder."""
    import sys
    from pathlib import Path

    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points

    out = Path((argv or sys.argv[1:] or ["."])[0])
    design, flat = cylinder_plate(spacing_mm=100.0)
    write_points(out / "long_cylinder_7500x2400_R20m.csv", design)
    write_points(out / "long_cylinder_7500x2400_R20m_flat.csv", flat)
    twisted, _ = twisted_plate(spacing_mm=100.0)
    write_points(out / "twisted_7500x2400.csv", twisted)
    write_points(out / "twisted_7500x2400_flat.csv", unfold(twisted).flat)
    (out / "plates.csv").write_text(MANIFEST)


MANIFEST = """name,design,flat,thickness_mm,material,springback
long_cylinder,long_cylinder_7500x2400_R20m.csv,long_cylinder_7500x2400_R20m_flat.csv,20,steel,no
twisted,twisted_7500x2400.csv,twisted_7500x2400_flat.csv,16,steel,no
kcs_stern_bilge,kcs_stern_bilge_9000x2400.csv,,20,steel,no
"""
"""The manifest of the bundled long plates (paths relative to it). The real hull plate
``kcs_stern_bilge_9000x2400.csv`` (KCS, stations 20-29 m, girth 3.0-5.4 m from the keel, 100 mm grid)
was cut from the hull model with ``mppf extract ../shared/data/cad/ship_kcs.igs --scale 31.6
--x 20000 29000 --girth 3000 5400 --spacing 100``; it is unfolded by the batch."""


if __name__ == "__main__":
    main()
