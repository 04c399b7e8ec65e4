"""The press description: punch matrices, limits and motion, loaded from TOML.

See ``docs/press.md`` for every key. All lengths are millimetres, speeds mm/s.
Press coordinates: origin at the centre of the matrix, x along the columns (the
matrix's longer axis), y along the rows, z up; the flat plate's bottom skin lies at
z = 0. The tip height of a lower punch is the top of its ball, of an upper punch the
bottom of its ball.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import ConfigError

MAX_ROWS = 32
MAX_COLS = 32
MAX_VALUE = 1.0e6
"""Largest magnitude of any number in a press description (mm, mm/s, mm/s^2): a
kilometre-sized value is a typing error, and would overflow the punch geometry."""


@dataclass(frozen=True)
class AxisLimits:
    """Tip-height limits of one matrix (mm, press z)."""

    min_mm: float
    max_mm: float
    park_mm: float


@dataclass(frozen=True)
class PressConfig:
    """A multi-point press.

    Attributes
    ----------
    rows, cols : int
        Punches along y and along x (at most 32 each).
    pitch_x_mm, pitch_y_mm : float
        Centre distance of neighbouring columns / rows.
    tip_radius_mm : float
        Radius of the spherical punch tips.
    upper, lower : AxisLimits
        Tip-height limits and parking height of the upper and lower matrices.
    max_neighbour_diff_mm : float
        Dimpling limit: the largest height difference between neighbouring punches
        that one press step may add.
    trim_allowance_mm : float
        Distance past the plate edge over which the surface is extended smoothly.
    speed_mm_s, accel_mm_s2 : float
        Punch speed and acceleration.
    position_tolerance_mm : float
        Largest |actual - target| accepted as in position.
    margin_mm : float
        Default trim margin: the excess band the flat plate is cut with around its net
        outline, so that punches also act beyond the net edge; trimmed after forming
        (0 = cut to the net outline).
    name : str
    """

    rows: int
    cols: int
    pitch_x_mm: float
    pitch_y_mm: float
    tip_radius_mm: float
    upper: AxisLimits
    lower: AxisLimits
    max_neighbour_diff_mm: float
    trim_allowance_mm: float = 100.0
    speed_mm_s: float = 20.0
    accel_mm_s2: float = 100.0
    position_tolerance_mm: float = 0.2
    margin_mm: float = 0.0
    name: str = "press"

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of each matrix."""
        return (self.rows, self.cols)

    @property
    def punch_x_mm(self) -> np.ndarray:
        """(cols,) x of the punch axes, centred on 0."""
        return (np.arange(self.cols) - (self.cols - 1) / 2.0) * self.pitch_x_mm

    @property
    def punch_y_mm(self) -> np.ndarray:
        """(rows,) y of the punch axes, centred on 0."""
        return (np.arange(self.rows) - (self.rows - 1) / 2.0) * self.pitch_y_mm

    @property
    def bed_size_mm(self) -> tuple[float, float]:
        """(x, y) extent between the outermost punch axes."""
        return ((self.cols - 1) * self.pitch_x_mm, (self.rows - 1) * self.pitch_y_mm)

    def to_dict(self) -> dict:
        """A plain dict in the TOML layout (for the job file)."""
        return {
            "name": self.name,
            "matrix": {
                "rows": self.rows,
                "cols": self.cols,
                "pitch_x_mm": self.pitch_x_mm,
                "pitch_y_mm": self.pitch_y_mm,
                "tip_radius_mm": self.tip_radius_mm,
            },
            "upper": dataclasses.asdict(self.upper),
            "lower": dataclasses.asdict(self.lower),
            "forming": {
                "max_neighbour_diff_mm": self.max_neighbour_diff_mm,
                "trim_allowance_mm": self.trim_allowance_mm,
                "speed_mm_s": self.speed_mm_s,
                "accel_mm_s2": self.accel_mm_s2,
                "position_tolerance_mm": self.position_tolerance_mm,
                "margin_mm": self.margin_mm,
            },
        }


_SPEC = {
    "matrix": {
        "rows": int,
        "cols": int,
        "pitch_x_mm": float,
        "pitch_y_mm": float,
        "tip_radius_mm": float,
    },
    "upper": {"min_mm": float, "max_mm": float, "park_mm": float},
    "lower": {"min_mm": float, "max_mm": float, "park_mm": float},
    "forming": {
        "max_neighbour_diff_mm": float,
        "trim_allowance_mm": (float, 100.0),
        "speed_mm_s": (float, 20.0),
        "accel_mm_s2": (float, 100.0),
        "position_tolerance_mm": (float, 0.2),
        "margin_mm": (float, 0.0),
    },
}


def _typed(source: str, table: str, key: str, value, kind):
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(
                f"{source}: [{table}] {key} must be a whole number, got {value!r}",
                hint="write it without a decimal point or quotes",
            )
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(
            f"{source}: [{table}] {key} must be a number in mm, got {value!r}",
            hint="write a plain number without quotes or units",
        )
    if not np.isfinite(value):
        raise ConfigError(f"{source}: [{table}] {key} must be finite, got {value!r}")
    if abs(value) > MAX_VALUE:
        raise ConfigError(f"{source}: [{table}] {key} is implausibly large, got {value!r}",
                          hint=f"give it in mm (mm/s for speeds), at most {MAX_VALUE:g} in size")
    return float(value)


def press_from_dict(data: dict, source: str = "press description") -> PressConfig:
    """Build and validate a :class:`PressConfig` from the TOML layout.

    Raises
    ------
    ConfigError
        On a missing table or key, an unknown key (likely mistyped), a wrong type or
        inconsistent limits; the message names the key and the value seen.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a table of press settings, got {type(data).__name__}")
    values: dict[str, object] = {}
    unknown_top = set(data) - set(_SPEC) - {"name"}
    if unknown_top:
        raise ConfigError(
            f"{source}: unknown table(s) {sorted(unknown_top)}",
            hint=f"the press description has the tables {sorted(_SPEC)} and 'name'",
        )
    for table, keys in _SPEC.items():
        section = data.get(table)
        if not isinstance(section, dict):
            raise ConfigError(
                f"{source}: missing table [{table}]",
                hint="see examples/press.toml and docs/press.md",
            )
        unknown = set(section) - set(keys)
        if unknown:
            raise ConfigError(
                f"{source}: unknown key(s) {sorted(unknown)} in [{table}]",
                hint=f"[{table}] takes {sorted(keys)}; check the spelling",
            )
        for key, kind in keys.items():
            default = None
            if isinstance(kind, tuple):
                kind, default = kind
            if key not in section:
                if default is None:
                    raise ConfigError(
                        f"{source}: missing key '{key}' in [{table}]",
                        hint="see examples/press.toml and docs/press.md",
                    )
                values[f"{table}.{key}"] = default
            else:
                values[f"{table}.{key}"] = _typed(source, table, key, section[key], kind)

    def v(name):
        return values[name]

    rows, cols = v("matrix.rows"), v("matrix.cols")
    for key, n, top in (("rows", rows, MAX_ROWS), ("cols", cols, MAX_COLS)):
        if not 1 <= n <= top:
            raise ConfigError(f"{source}: [matrix] {key} must be 1..{top}, got {n}")
    positive = [
        "matrix.pitch_x_mm",
        "matrix.pitch_y_mm",
        "matrix.tip_radius_mm",
        "forming.max_neighbour_diff_mm",
        "forming.speed_mm_s",
        "forming.accel_mm_s2",
        "forming.position_tolerance_mm",
    ]
    for name in positive:
        if v(name) <= 0:
            table, key = name.split(".")
            raise ConfigError(f"{source}: [{table}] {key} must be positive, got {v(name)}")
    if v("forming.trim_allowance_mm") < 0:
        raise ConfigError(
            f"{source}: [forming] trim_allowance_mm must be >= 0, got {v('forming.trim_allowance_mm')}"
        )
    if v("forming.margin_mm") < 0:
        raise ConfigError(f"{source}: [forming] margin_mm must be >= 0, got {v('forming.margin_mm')}")
    if 2 * v("matrix.tip_radius_mm") > min(v("matrix.pitch_x_mm"), v("matrix.pitch_y_mm")):
        raise ConfigError(
            f"{source}: [matrix] tip_radius_mm {v('matrix.tip_radius_mm')} is too large for the pitch "
            f"({v('matrix.pitch_x_mm')} x {v('matrix.pitch_y_mm')} mm): neighbouring balls would overlap"
        )
    limits = {}
    for side in ("upper", "lower"):
        lo, hi, park = v(f"{side}.min_mm"), v(f"{side}.max_mm"), v(f"{side}.park_mm")
        if not lo < hi:
            raise ConfigError(f"{source}: [{side}] min_mm ({lo}) must be below max_mm ({hi})")
        if not lo <= park <= hi:
            raise ConfigError(
                f"{source}: [{side}] park_mm ({park}) must lie within min_mm..max_mm ({lo}..{hi})"
            )
        limits[side] = AxisLimits(lo, hi, park)
    name = data.get("name", "press")
    if not isinstance(name, str):
        raise ConfigError(f"{source}: name must be a string, got {name!r}")
    return PressConfig(
        rows=rows,
        cols=cols,
        pitch_x_mm=v("matrix.pitch_x_mm"),
        pitch_y_mm=v("matrix.pitch_y_mm"),
        tip_radius_mm=v("matrix.tip_radius_mm"),
        upper=limits["upper"],
        lower=limits["lower"],
        max_neighbour_diff_mm=v("forming.max_neighbour_diff_mm"),
        trim_allowance_mm=v("forming.trim_allowance_mm"),
        speed_mm_s=v("forming.speed_mm_s"),
        accel_mm_s2=v("forming.accel_mm_s2"),
        position_tolerance_mm=v("forming.position_tolerance_mm"),
        margin_mm=v("forming.margin_mm"),
        name=name,
    )


def load_press(path) -> PressConfig:
    """Read a press description from a TOML file.

    Raises
    ------
    ConfigError
        The file is missing, is not valid TOML, or has missing/mistyped keys.
    """
    path = Path(path)
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"press description {path} does not exist", hint="give the path of a .toml file") from None
    except IsADirectoryError:
        raise ConfigError(f"press description {path} is a directory, not a file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}", hint="see examples/press.toml") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a text (TOML) file") from None
    return press_from_dict(data, source=str(path))


def example_press_path() -> Path:
    """Path of the bundled example press description."""
    return Path(__file__).resolve().parents[1] / "examples" / "press.toml"
