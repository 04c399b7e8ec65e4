"""The press description: punch matrices, limits and motion, loaded from TOML (shared by every stage).

See ``docs/press.md`` for every key. All lengths are millimetres, speeds mm/s.
Press coordinates: origin at the centre of the matrix, x along the columns (the
matrix's longer axis), y along the rows, z up; the flat plate's bottom skin lies at
z = 0. The tip height of a lower punch is the top of its ball, of an upper punch the
bottom of its ball.
"""

from __future__ import annotations

import contextlib
import dataclasses
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import ConfigError
from mppf.core.validate import check_number

MAX_ROWS = 32
MAX_COLS = 32
MAX_VALUE = 1.0e6
"""Largest magnitude of any number in a press description (mm, mm/s, mm/s^2): a
kilometre-sized value is a typing error, and would overflow the punch geometry."""


def _length(name: str, value, *, low: float | None = -MAX_VALUE, low_open: bool = False) -> float:
    """A press setting as a float within ``low``..``MAX_VALUE`` (:func:`mppf.core.validate.check_number`)."""
    unit = "mm/s^2" if name.endswith("_mm_s2") else "mm/s" if name.endswith("_mm_s") else "mm"
    return float(check_number(name, value, low=low, low_open=low_open, high=MAX_VALUE, unit=unit, error=ConfigError))


@dataclass(frozen=True)
class AxisLimits:
    """Tip-height limits of one matrix (mm, press z).

    Checked when built: finite numbers of at most ``MAX_VALUE``, ``min_mm < max_mm`` and the
    parking height within them (:class:`ConfigError` otherwise).
    """

    min_mm: float
    max_mm: float
    park_mm: float

    def __post_init__(self):
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _length(f.name, getattr(self, f.name)))
        if not self.min_mm < self.max_mm:
            raise ConfigError(f"min_mm ({self.min_mm}) must be below max_mm ({self.max_mm})")
        if not self.min_mm <= self.park_mm <= self.max_mm:
            raise ConfigError(f"park_mm ({self.park_mm}) must lie within min_mm..max_mm "
                              f"({self.min_mm}..{self.max_mm})")


@dataclass(frozen=True)
class PressConfig:
    """A multi-point press.

    Checked when built, in code as from a file (:func:`press_from_dict`): every number
    finite and within its range (:func:`mppf.core.validate.check_number`), the balls not
    overlapping; :class:`ConfigError` names the key (``[matrix] rows``) and the value seen.

    Attributes
    ----------
    rows, cols : int
        Punches along y and along x (at most 32 each).
    pitch_x_mm, pitch_y_mm : float
        Centre distance of neighbouring columns / rows.
    tip_radius_mm : float
        Radius of the spherical punch tips (at most half the smaller pitch).
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
    max_thickness_mm : float
        The thickest plate the press takes. The parked tips must leave at least this much
        between them (``upper.park_mm - lower.park_mm``), and no job may be thicker.
    label_base : int
        How the press labels its punches in messages: 1 (row 1, column 1 is the first
        punch, the default) or 0.
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
    trim_allowance_mm: float = 100.0  # the surface extended 100 mm past the plate edge
    speed_mm_s: float = 20.0
    accel_mm_s2: float = 100.0
    position_tolerance_mm: float = 0.2
    margin_mm: float = 0.0  # cut to the net outline
    max_thickness_mm: float = 50.0  # the thickest plate; the parks leave at least this between them
    label_base: int = 1  # punches are named from row 1, column 1
    name: str = "press"

    def __post_init__(self):
        for table in ("matrix", "forming"):
            for key in _TABLES[table]:
                name = f"[{table}] {key}"
                if key in _COUNTS:
                    low, high = _COUNTS[key]
                    value = check_number(name, getattr(self, key), low=low, high=high, integer=True,
                                         error=ConfigError)
                else:
                    value = _length(name, getattr(self, key), low=0.0, low_open=key not in _AT_LEAST_ZERO)
                object.__setattr__(self, key, value)
        for side in ("upper", "lower"):
            if not isinstance(getattr(self, side), AxisLimits):
                raise ConfigError(f"[{side}] must be the tip-height limits (AxisLimits), got "
                                  f"{getattr(self, side)!r}")
        if 2 * self.tip_radius_mm > min(self.pitch_x_mm, self.pitch_y_mm):
            raise ConfigError(
                f"[matrix] tip_radius_mm {self.tip_radius_mm} is too large for the pitch "
                f"({self.pitch_x_mm} x {self.pitch_y_mm} mm): neighbouring balls would overlap"
            )
        if not isinstance(self.name, str):
            raise ConfigError(f"name must be a string, got {self.name!r}")
        self._check_parks()

    def _check_parks(self) -> None:
        """The parked tips must not cross and must leave room for the thickest plate."""
        gap = self.upper.park_mm - self.lower.park_mm
        if gap < 0:
            raise ConfigError(f"[upper] park_mm {self.upper.park_mm:g} mm is below [lower] park_mm "
                              f"{self.lower.park_mm:g} mm: the parked tips would cross",
                              hint="park the upper punches above the lower ones (docs/press.md, parking heights)")
        if gap < self.max_thickness_mm:
            raise ConfigError(f"[upper] park_mm {self.upper.park_mm:g} mm and [lower] park_mm "
                              f"{self.lower.park_mm:g} mm "
                              f"leave {gap:g} mm between the parked tips, less than the largest plate thickness "
                              f"[forming] max_thickness_mm {self.max_thickness_mm:g} mm",
                              hint="move the parks apart or lower max_thickness_mm (docs/press.md, parking heights)")

    def punch_label(self, row: int, col: int) -> str:
        """How the press names punch ``[row, col]`` (0-based indices): ``"row 3, col 4"`` from row 1."""
        return f"row {int(row) + self.label_base}, col {int(col) + self.label_base}"

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
            "matrix": {key: getattr(self, key) for key in _TABLES["matrix"]},
            "upper": dataclasses.asdict(self.upper),
            "lower": dataclasses.asdict(self.lower),
            "forming": {key: getattr(self, key) for key in _TABLES["forming"]},
        }


_TABLES = {
    "matrix": ("rows", "cols", "pitch_x_mm", "pitch_y_mm", "tip_radius_mm", "label_base"),
    "upper": tuple(f.name for f in dataclasses.fields(AxisLimits)),
    "lower": tuple(f.name for f in dataclasses.fields(AxisLimits)),
    "forming": ("max_neighbour_diff_mm", "trim_allowance_mm", "speed_mm_s", "accel_mm_s2", "position_tolerance_mm",
                "margin_mm", "max_thickness_mm"),
}
"""The tables of the TOML layout and their keys, in file order (the PressConfig and AxisLimits fields)."""

_COUNTS = {"rows": (1, MAX_ROWS), "cols": (1, MAX_COLS), "label_base": (0, 1)}
"""The whole-number keys and their smallest and largest values."""

_AT_LEAST_ZERO = ("trim_allowance_mm", "margin_mm")
"""Lengths that may be 0; every other press length must be positive."""

_DEFAULTS = {f.name: f.default for f in dataclasses.fields(PressConfig) if f.default is not dataclasses.MISSING}
"""Keys that may be left out of a press description (their defaults are the dataclass's)."""


def press_from_dict(data: dict, source: str = "press description") -> PressConfig:
    """Build and validate a :class:`PressConfig` from the TOML layout.

    The tables and keys are read here (missing, unknown, an integer key written with a
    decimal point); the values are checked by the dataclasses themselves.

    Raises
    ------
    ConfigError
        On a missing table or key, an unknown key (likely mistyped), a wrong type or
        inconsistent limits; the message starts with ``source`` and names the key and the
        value seen.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a table of press settings, got {type(data).__name__}")
    unknown_top = set(data) - set(_TABLES) - {"name"}
    if unknown_top:
        raise ConfigError(
            f"{source}: unknown table(s) {sorted(unknown_top)}",
            hint=f"the press description has the tables {sorted(_TABLES)} and 'name'",
        )
    tables = {table: _read_table(data, table, source) for table in _TABLES}
    limits = {}
    for side in ("upper", "lower"):
        with _named(f"{source}: [{side}] "):
            limits[side] = AxisLimits(**tables[side])
    with _named(f"{source}: "):
        return PressConfig(**tables["matrix"], **tables["forming"], **limits, name=data.get("name", "press"))


def _read_table(data: dict, table: str, source: str) -> dict:
    """The keys of one table, as given (missing optional keys left to the dataclass's defaults)."""
    section = data.get(table)
    if not isinstance(section, dict):
        raise ConfigError(f"{source}: missing table [{table}]", hint="see examples/press.toml and docs/press.md")
    keys = _TABLES[table]
    unknown = set(section) - set(keys)
    if unknown:
        raise ConfigError(f"{source}: unknown key(s) {sorted(unknown)} in [{table}]",
                          hint=f"[{table}] takes {sorted(keys)}; check the spelling")
    for key in keys:
        if key not in section and (table in ("upper", "lower") or key not in _DEFAULTS):
            raise ConfigError(f"{source}: missing key '{key}' in [{table}]",
                              hint="see examples/press.toml and docs/press.md")
    for key in _COUNTS:
        if isinstance(section.get(key), float):  # TOML tells 16 from 16.0: a count is written without a point
            raise ConfigError(f"{source}: [{table}] {key} must be a whole number, got {section[key]!r}",
                              hint="write it without a decimal point or quotes")
    return dict(section)


@contextlib.contextmanager
def _named(prefix: str):
    """Re-raise a dataclass's ConfigError with where it came from (file and table) in front."""
    try:
        yield
    except ConfigError as exc:
        raise ConfigError(prefix + exc.message, hint=exc.hint) from None


def load_press(path) -> PressConfig:
    """Read a press description from a TOML file.

    Raises
    ------
    ConfigError
        The file is missing, is not valid TOML, or has missing/mistyped keys.
    """
    import stat

    path = Path(path)
    try:
        info = path.stat()
        if not stat.S_ISDIR(info.st_mode) and (not stat.S_ISREG(info.st_mode) or info.st_size > MAX_PRESS_BYTES):
            raise ConfigError(f"press description {path} is not a press description: "
                              + ("not a regular file (a device, a pipe or a socket)" if not stat.S_ISREG(info.st_mode)
                                 else f"{info.st_size:,} bytes, a press description is at most {MAX_PRESS_BYTES:,}"),
                              hint="give the path of the press's .toml file (see examples/press.toml)")
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


MAX_PRESS_BYTES = 1_000_000
"""The largest press description read (the example is 2 kB)."""


def example_press_path() -> Path:
    """Path of the bundled example press description."""
    return Path(__file__).resolve().parents[1] / "examples" / "press.toml"


def press_to_toml(press: PressConfig) -> str:
    """A press description as TOML text that :func:`load_press` reads back equal (its name, then each table).

    For installing a machine's press (``$MPPF_HOME/press.toml``) and for tests.
    """
    import json

    lines, tables = [], []
    for key, value in press.to_dict().items():
        if isinstance(value, dict):
            tables.append((key, value))
        else:
            lines.append(f"{key} = {json.dumps(value)}")
    for table, block in tables:
        lines += ["", f"[{table}]"] + [f"{key} = {json.dumps(value)}" for key, value in block.items()]
    return "\n".join(lines) + "\n"
