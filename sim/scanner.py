"""Simulated 3D scanner: samples a formed plate's top skin as a real scan would.

A scan (see ``docs/compare.md``, section "The simulated scanner") is

- the top skin of the unloaded plate sampled on a grid of ``spacing_mm`` with a small
  random jitter (a scanner does not hit the CAD grid),
- with isotropic Gaussian noise of ``noise_mm`` per coordinate,
- with ``occlusion_fraction`` of the plate missing as one or two contiguous elliptic
  blobs (clamps, the crane hook, shadows), not as random points,
- with ``outlier_fraction`` of the points thrown 5-50 mm off the surface along its normal
  (reflections, dust),
- in an arbitrary rigid pose (a random rotation and a translation of up to 2 m): the
  scanner knows nothing of the press coordinates. With ``max_turn_deg`` the rotation is
  a turn about the vertical only (a scanner mounted over the press table). A pose may be
  given instead (``tf_scan_press``): a fixed station's second take of the same plate, in
  the frame of its first (a rescan),
- optionally with the plate's reference-corner mark picked in the scan (``mark_xy_mm``):
  its position in the scanner's coordinates, as the operator would click it in the
  scanner software (within a few mm), written next to the scan as
  ``<scan file>.mark.json`` (:data:`mppf.measure.mark.MARK_SUFFIX`). The pose stays arbitrary.

The scanner owns one seeded random generator: successive scans differ, the sequence is
reproducible. Build a new scanner with the same seed to repeat a scan.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.polygon import contains, convex_outline, offset_convex
from mppf.core.validate import check_number
from mppf.geometry.write import write_points
from mppf.measure.mark import MARK_SUFFIX
from mppf.sim.forming import FormedPlate
from mppf.core.transform import apply_tf, make_tf

OUTLIER_OFFSET_MM = (5.0, 50.0)
"""Range of the distance of outliers from the surface."""

MAX_TRANSLATION_MM = 2000.0
"""Largest component of the random translation of the scan pose."""

MARK_PICK_MM = 5.0
"""Standard deviation (per coordinate) of picking the reference mark in the scan."""


@dataclass(frozen=True, eq=False)
class ScanSample:
    """One simulated scan with its ground truth.

    Attributes
    ----------
    points : (n, 3) float
        The scan, in the scanner's coordinates, mm.
    tf_scan_press : (4, 4) float
        The pose: maps press coordinates into the scanner's.
    is_outlier : (n,) bool
        Which points are outliers.
    occluded_fraction : float
        Fraction of the plate's sample points hidden by the occlusion blobs.
    n_blobs : int
        Number of occlusion blobs (1 or 2; 0 without occlusion).
    hidden_xy_mm : (m, 2) float
        Press (x, y) of the sample positions hidden by the blobs.
    mark_mm : (3,) float or None
        The reference mark as picked in the scan (scanner coordinates), when asked for.
    """

    points: np.ndarray
    tf_scan_press: np.ndarray
    is_outlier: np.ndarray
    occluded_fraction: float
    n_blobs: int
    hidden_xy_mm: np.ndarray
    mark_mm: np.ndarray | None = None


AIM_MARGIN_SPACINGS = 3.0
"""An aimed take (a rescan of listed areas) scans this many point spacings around each area too."""


class SimulatedScanner:
    """A seeded simulated scanner.

    Parameters
    ----------
    noise_mm : float
        Standard deviation of the Gaussian noise per coordinate (so also along the normal).
    occlusion_fraction : float
        Fraction of the plate missing, in [0, 0.9].
    outlier_fraction : float
        Fraction of the returned points that are outliers, in [0, 0.5].
    spacing_mm : float
        Sampling distance on the plate.
    seed : int
        Seed of the scanner's random generator.
    max_turn_deg : float, optional
        None (default): the pose is an arbitrary rotation. A number: the scanner looks
        down on the press table with its z axis up, and the pose is a turn about z of at
        most this many degrees (plus the random shift).
    """

    def __init__(
        self,
        noise_mm: float = 0.3,
        occlusion_fraction: float = 0.2,
        outlier_fraction: float = 0.01,
        spacing_mm: float = 20.0,
        seed: int = 0,
        max_turn_deg: float | None = None,
    ):
        checks = (
            ("noise_mm", noise_mm, 0.0, 50.0),
            ("occlusion_fraction", occlusion_fraction, 0.0, 0.9),
            ("outlier_fraction", outlier_fraction, 0.0, 0.5),
            ("spacing_mm", spacing_mm, 1.0, 1000.0),
        )
        for name, value, lo, hi in checks:
            check_number(f"scanner {name}", value, low=lo, high=hi)
        self.noise_mm = float(noise_mm)
        self.occlusion_fraction = float(occlusion_fraction)
        self.outlier_fraction = float(outlier_fraction)
        self.spacing_mm = float(spacing_mm)
        if max_turn_deg is not None:
            check_number("scanner max_turn_deg", max_turn_deg, low=0.0, high=180.0, unit="deg")
        self.max_turn_deg = max_turn_deg
        self.seed = seed
        self._rng = np.random.default_rng(seed)

    def sample(self, formed: FormedPlate, mark_xy_mm=None, tf_scan_press=None, aim_xy_mm=()) -> ScanSample:
        """Scan ``formed`` and return the points with their ground truth.

        Parameters
        ----------
        formed : FormedPlate
        mark_xy_mm : (2,) float, optional
            Press (x, y) of the plate's reference-corner mark: its top-skin point is
            returned in the scanner's coordinates (picked within ``MARK_PICK_MM``).
        tf_scan_press : (4, 4) float, optional
            The pose to scan in (a fixed station's take in the frame of an earlier one);
            default a random pose. The random draws are the same either way.
        aim_xy_mm : sequence of (k, 2) float, optional
            A take aimed at these areas (press x, y corners, e.g. a rescan request's): only the
            plate within :data:`AIM_MARGIN_SPACINGS` point spacings of their convex outlines is
            scanned (the occlusion, if any, applies to that part).

        Returns
        -------
        ScanSample
        """
        rng = self._rng
        # 1. sample positions on the plate (grid + jitter), top skin
        xy = formed.sample_xy(self.spacing_mm)
        xy = xy + rng.uniform(-0.5, 0.5, xy.shape) * self.spacing_mm
        # the jitter must not carry a point past the plate's edge (there is no plate there)
        xy = xy[contains(formed.outline_xy_mm, xy)]
        if len(aim_xy_mm):  # an aimed take: the listed areas and a rim around them
            xy = xy[self._aimed(xy, aim_xy_mm)]
        # 2. occlusion: drop the points nearest to one or two random blob centres
        keep, n_blobs = self._occlusion_mask(xy, rng)
        occluded = 1.0 - keep.mean()
        hidden = xy[~keep]
        xy = xy[keep]
        normals = formed.normals(xy)
        points = formed.offset_points(xy, 0.5 * formed.thickness_mm)
        # 3. noise
        points = points + rng.normal(0.0, self.noise_mm, points.shape) if self.noise_mm > 0 else points
        # 4. outliers along the normal, either side
        is_outlier = self._add_outliers(points, normals, rng)
        # 5. arbitrary pose; shuffle the order as a scanner would not keep the grid order
        random_pose = self._random_pose(rng)
        tf_scan_press = random_pose if tf_scan_press is None else np.asarray(tf_scan_press, dtype=float)
        order = rng.permutation(len(points))
        mark = None
        if mark_xy_mm is not None:  # drawn last: the scan itself is the same with or without
            on_skin = formed.offset_points(np.asarray(mark_xy_mm, dtype=float).reshape(1, 2),
                                           0.5 * formed.thickness_mm)
            mark = apply_tf(tf_scan_press, on_skin)[0] + rng.normal(0.0, MARK_PICK_MM, 3)
        return ScanSample(
            points=apply_tf(tf_scan_press, points[order]),
            tf_scan_press=tf_scan_press,
            is_outlier=is_outlier[order],
            occluded_fraction=float(occluded),
            n_blobs=n_blobs,
            hidden_xy_mm=hidden,
            mark_mm=mark,
        )

    def _aimed(self, xy: np.ndarray, aim_xy_mm) -> np.ndarray:
        """(n,) bool: the points (n, 2) mm within the aimed areas' convex outlines grown by the margin."""
        grow = AIM_MARGIN_SPACINGS * self.spacing_mm
        aimed = np.zeros(len(xy), dtype=bool)
        for corners in aim_xy_mm:
            aimed |= contains(offset_convex(convex_outline(np.asarray(corners, dtype=float), "an aimed area"),
                                            grow), xy)
        return aimed

    def _add_outliers(self, points: np.ndarray, normals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Move a fraction of the points (n, 3) mm along their normals, either side, in place; (n,) bool which."""
        n_out = int(round(self.outlier_fraction * len(points)))
        is_outlier = np.zeros(len(points), dtype=bool)
        if n_out:
            idx = rng.choice(len(points), n_out, replace=False)
            offset = rng.uniform(*OUTLIER_OFFSET_MM, n_out) * rng.choice([-1.0, 1.0], n_out)
            points[idx] += offset[:, None] * normals[idx]
            is_outlier[idx] = True
        return is_outlier

    def _random_pose(self, rng: np.random.Generator) -> np.ndarray:
        """A (4, 4) pose: any rotation (or a turn about z within ``max_turn_deg``) and a shift (mm)."""
        if self.max_turn_deg is None:
            rotation = Rotation.random(random_state=rng).as_matrix()
        else:
            turn = rng.uniform(-self.max_turn_deg, self.max_turn_deg)
            rotation = Rotation.from_euler("z", turn, degrees=True).as_matrix()
        return make_tf(rotation, rng.uniform(-MAX_TRANSLATION_MM, MAX_TRANSLATION_MM, 3))

    def _occlusion_mask(self, xy: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, int]:
        n = len(xy)
        n_hidden = int(round(self.occlusion_fraction * n))
        if n_hidden == 0:
            return np.ones(n, dtype=bool), 0
        n_blobs = int(rng.integers(1, 3))
        share = np.full(n_blobs, n_hidden // n_blobs)
        share[0] += n_hidden - share.sum()
        keep = np.ones(n, dtype=bool)
        for count in share:
            # an ellipse of random orientation and aspect around a random plate point
            centre = xy[rng.integers(n)]
            angle = rng.uniform(0, np.pi)
            aspect = rng.uniform(1.0, 2.5)
            c, s = np.cos(angle), np.sin(angle)
            d = xy - centre
            dist = np.hypot(d @ [c, s], (d @ [-s, c]) * aspect)
            dist[~keep] = np.inf
            keep[np.argsort(dist, kind="stable")[:count]] = False
        return keep, n_blobs

    def scan_points(self, formed: FormedPlate) -> np.ndarray:
        """Scan ``formed``; (n, 3) float points in the scanner's coordinates, mm."""
        return self.sample(formed).points

    def scan(self, formed: FormedPlate, path, mark_xy_mm=None, tf_scan_press=None, aim_xy_mm=()) -> Path:
        """Scan ``formed`` and write the points to ``path`` (.ply binary, .csv, .txt, .xyz).

        With ``mark_xy_mm`` (press x, y of the reference-corner mark) the mark picked in
        the scan is also written to ``<path>.mark.json`` as ``{"reference_mark_mm": [x, y, z]}``
        in the scan's coordinates. ``tf_scan_press``: the pose, ``aim_xy_mm``: the areas of an aimed take
        (see :meth:`sample`).

        Returns
        -------
        Path
            The file written.
        """
        sample = self.sample(formed, mark_xy_mm, tf_scan_press, aim_xy_mm)
        header = (f"simulated scan: noise {self.noise_mm} mm, occlusion {sample.occluded_fraction:.3f}, "
                  f"outliers {int(sample.is_outlier.sum())}, seed {self.seed}")
        written = write_points(path, sample.points, header=header)
        if sample.mark_mm is not None:
            mark_doc = {"reference_mark_mm": [float(v) for v in sample.mark_mm],
                        "frame": "scan coordinates, mm (the reference-corner mark as picked in the scan)"}
            Path(str(written) + MARK_SUFFIX).write_text(json.dumps(mark_doc, indent=2) + "\n")
        return written
