"""Batch planning: many plates of a hull block unfolded and planned at once, resumably.

The batch is a list of :class:`Plate` (from design files or a CSV manifest, :func:`read_manifest`);
:func:`run_batch` plans them in a process pool (one plate per task: read, unfold unless a flat is
given, plan in one piece or in sections, write the job), skipping every plate whose finished job
holds the same input key (:func:`input_key`: the SHA-256 of its files, the press and the options),
and returns one summary row per plate. A plate that fails is a row with its reason; it does not stop
the batch. The summary files are :mod:`mppf.planning.batch_summary`. See ``docs/sections.md``.

This module is the batch's orchestration: it reads and writes files (design, flat, job) through the
readers and writers of :mod:`mppf.geometry` and :mod:`mppf.planning.job`; the planning itself stays pure.
"""

from __future__ import annotations

import csv
import hashlib
import json
import time
from concurrent.futures import as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

from mppf.core.errors import FileFormatError, InputError, MppfError
from mppf.core.progress import NULL_REPORTER
from mppf.core.validate import check_name
from mppf.model.job_provenance import BatchRecord
from mppf.model.material import MATERIALS
from mppf.planning.batch_pool import planning_pool

MANIFEST_COLUMNS = ("name", "design", "flat", "thickness_mm", "material", "springback")
"""Columns of a manifest; ``design`` and ``thickness_mm`` are required (thickness may come from ``--thickness``)."""
MAX_MANIFEST_BYTES = 50_000_000
"""The largest manifest read (a row is about 100 bytes)."""
KEY_VERSION = 1
"""Bumped when the meaning of the input key changes (finished jobs are then planned again)."""


@dataclass(frozen=True)
class Plate:
    """One plate of a batch.

    Attributes
    ----------
    name : str
        Unique in the batch; the job is ``<name>.job.json``.
    design : str
        Path of the design file.
    flat : str or None
        Path of its flat; None: unfolded in the batch (``<name>.flat.csv`` written).
    thickness_mm : float
    material : str or None
        A name of :data:`mppf.model.material.MATERIALS`.
    springback : bool
    """

    name: str
    design: str
    flat: str | None
    thickness_mm: float
    material: str | None = None
    springback: bool = False


@dataclass(frozen=True)
class BatchOptions:
    """What every plate of a batch shares.

    Attributes
    ----------
    press_path : str
    out_dir : str
    units : str
        Of the design and flat files ("mm" or "m").
    margin_mm, transition_mm : float or None
        Trim margin and least transition width (None: the press's and the planner's defaults).
    workers : int
        Processes of the pool (1: in this process).
    """

    press_path: str
    out_dir: str
    units: str = "mm"
    margin_mm: float | None = None
    transition_mm: float | None = None
    workers: int = 1


def plates_from_files(paths, thickness_mm, material: str | None = None, springback: bool = False) -> list[Plate]:
    """Plates from design files, all of one thickness and material (each unfolded in the batch).

    Raises
    ------
    InputError
        No files, a missing file, no thickness, two files of the same name.
    """
    if not paths:
        raise InputError("no plates given", hint="give design files or --manifest PLATES.csv")
    if thickness_mm is None:
        raise InputError("the plate thickness is missing", hint="give --thickness MM (or a manifest with thickness_mm)")
    plates = [Plate(Path(p).stem, str(p), None, float(thickness_mm), material, springback) for p in paths]
    for plate in plates:
        check_name(f"the plate name (the stem of {plate.design})", plate.name,
                   hint="the job is written as <name>.job.json in -o; rename the file, or use a --manifest with names")
    return _checked(plates, "the design files")


def read_manifest(path, default_thickness_mm=None, default_material: str | None = None, *,
                  max_thickness_mm: float | None = None) -> list[Plate]:
    """The plates of a CSV manifest (columns :data:`MANIFEST_COLUMNS`; paths relative to its folder).

    A plate's name (the ``name`` column, else its design file's stem) names its job and flat
    files in the output folder, so it must be a plain name (:func:`mppf.core.validate.check_name`):
    never a path. A row with more fields than the header, or a thickness above
    ``max_thickness_mm`` (the press's), is refused with its line.

    Raises
    ------
    InputError
        The manifest is missing or unreadable; FileFormatError for a row with a bad value (file and line named).
    """
    path = Path(path)
    try:
        if path.exists() and (not path.is_file() or path.stat().st_size > MAX_MANIFEST_BYTES):
            raise InputError(f"manifest {path} is not a manifest: "
                             + ("not a regular file (a folder, a device or a pipe)" if not path.is_file() else
                                f"{path.stat().st_size:,} bytes, a manifest is at most {MAX_MANIFEST_BYTES:,}"),
                             hint="give the CSV file listing the plates")
        with path.open(newline="") as f:
            rows = list(csv.DictReader(f))
    except FileNotFoundError:
        raise InputError(f"manifest {path} does not exist", hint="give the CSV file listing the plates") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"manifest {path} cannot be read: {exc}") from None
    if not rows or "design" not in rows[0]:
        raise FileFormatError(path, f"a manifest needs a header with at least 'design' (and 'thickness_mm'); "
                                    f"got {list(rows[0]) if rows else 'no rows'}",
                              hint=f"columns: {', '.join(MANIFEST_COLUMNS)}")
    plates = [_manifest_plate(row, path, line, default_thickness_mm, default_material, max_thickness_mm)
              for line, row in enumerate(rows, start=2)]
    return _checked(plates, str(path))


def _manifest_plate(row: dict, path: Path, line: int, default_thickness_mm, default_material,
                    max_thickness_mm=None) -> Plate:
    def bad(message: str, hint: str | None = None):
        return FileFormatError(path, message, line=line, hint=hint)

    if row.get(None):  # csv.DictReader puts the fields beyond the header's under None
        surplus = row[None]
        raise bad(f"the row has {len(surplus)} field(s) more than the header's {len(row) - 1} column(s): "
                  f"{', '.join(repr(v) for v in surplus[:3])}",
                  "remove them, or quote a value that holds a comma (\"a,b\")")
    design = (row.get("design") or "").strip()
    if not design:
        raise bad("no design file", "every row names its design file")
    text = (row.get("thickness_mm") or "").strip()
    if not text and default_thickness_mm is None:
        raise bad("no thickness_mm", "fill the column or give --thickness MM")
    try:
        thickness = float(text) if text else float(default_thickness_mm)
    except ValueError:
        raise bad(f"thickness_mm {text!r} is not a number", "e.g. 20") from None
    if not 0.0 < thickness < float("inf"):
        raise bad(f"thickness_mm {thickness:g} is not a positive number of mm", "e.g. 20")
    if max_thickness_mm is not None and thickness > max_thickness_mm:
        raise bad(f"thickness_mm {thickness:g} mm is above the largest plate the press takes, {max_thickness_mm:g} mm",
                  "check the thickness column (mm)")
    material = (row.get("material") or "").strip() or default_material
    if material is not None and material not in MATERIALS:
        raise bad(f"material {material!r} is not known", f"one of {', '.join(sorted(MATERIALS))}")
    springback = (row.get("springback") or "").strip().lower()
    if springback not in ("", "yes", "no", "true", "false", "1", "0"):
        raise bad(f"springback {springback!r} is not yes or no")
    if springback in ("yes", "true", "1") and material is None:
        raise bad("springback needs the plate's material", "fill the material column (steel, ah36)")
    flat = (row.get("flat") or "").strip()
    base = path.parent
    name = (row.get("name") or "").strip() or Path(design).stem
    try:
        check_name("plate name", name, hint="the job is written as <name>.job.json in -o; e.g. B12-P3")
    except InputError as exc:
        raise bad(exc.message, exc.hint) from None
    return Plate(name=name, design=str(base / design),
                 flat=str(base / flat) if flat else None, thickness_mm=thickness, material=material,
                 springback=springback in ("yes", "true", "1"))


def _checked(plates: list[Plate], source: str) -> list[Plate]:
    names = [p.name for p in plates]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"{source}: plate names must be unique, {', '.join(twice[:5])} appear more than once",
                         hint="give each row its own 'name'")
    missing = [p.design for p in plates if not Path(p.design).is_file()]
    missing += [p.flat for p in plates if p.flat and not Path(p.flat).is_file()]
    if missing:
        raise InputError(f"{source}: {len(missing)} file(s) do not exist: {', '.join(missing[:5])}",
                         hint="check the paths (relative to the manifest's folder)")
    return plates


def file_sha256(path) -> str:
    """Hex SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def input_key(plate: Plate, options: BatchOptions) -> str:
    """The SHA-256 of everything a plate's job depends on: its files, the press and the options."""
    doc = {"key_version": KEY_VERSION, "design": file_sha256(plate.design),
           "flat": file_sha256(plate.flat) if plate.flat else "unfolded", "press": file_sha256(options.press_path),
           "thickness_mm": plate.thickness_mm, "material": plate.material, "springback": plate.springback,
           "units": options.units, "margin_mm": options.margin_mm, "transition_mm": options.transition_mm}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def job_path(plate: Plate, options: BatchOptions) -> Path:
    return Path(options.out_dir) / f"{plate.name}.job.json"


def finished_row(plate: Plate, options: BatchOptions, key: str) -> dict | None:
    """The summary row of a finished job with this input key, or None (no job, another key, unreadable)."""
    from mppf.core.seal import SealError
    from mppf.planning.job import load_job

    path = job_path(plate, options)
    if not path.is_file():
        return None
    try:
        job = load_job(path)
    except SealError as exc:  # planned again (the edited job is replaced), and said so in the summary
        row = plan_plate_files(plate, options, key)
        note = f"the job in the output folder had been changed after it was sealed, planned again ({exc.message})"
        return {**row, "warnings": "; ".join(w for w in (row.get("warnings"), note) if w)}
    except InputError:
        return None
    if job.batch is None or job.batch.key != key:
        return None
    return {**(job.batch.row or {}), "status": "skipped", "reason": "inputs unchanged since the finished job"}


def plan_plate_files(plate: Plate, options: BatchOptions, key: str) -> dict:
    """Read, unfold (unless a flat is given), plan and save one plate; its summary row. Runs in a worker."""
    from mppf.geometry.read import read_points
    from mppf.model.plan_options import PlanOptions
    from mppf.model.press import load_press
    from mppf.planning.job import save_job
    from mppf.planning.sectional import plan_plate

    started, cpu_started = time.perf_counter(), time.process_time()
    press = load_press(options.press_path)
    design = read_points(plate.design, units=options.units)
    warnings = list(design.warnings)
    # 1. the flat plate: given, or unfolded here (and written beside the job)
    flat_points, strain_pct, flat_path = _flat(plate, options, design, warnings)
    # 2. plan in one piece, or in sections when the plate is larger than the bed
    material = MATERIALS[plate.material] if plate.material else None
    inputs = {"design": {"path": plate.design, "sha256": design.sha256},
              "flat": {"path": flat_path, "sha256": file_sha256(flat_path)},
              "press": {"path": options.press_path, "sha256": file_sha256(options.press_path)}, "units": options.units}
    plan_options = PlanOptions(material=material, springback=plate.springback, margin_mm=options.margin_mm,
                               transition_mm=options.transition_mm)
    job = plan_plate(design.points, flat_points, press, plate.thickness_mm, plan_options, design_faces=design.faces,
                     inputs=inputs)
    if strain_pct is None:
        strain_pct = None if job.reports.registration is None else job.reports.registration.neighbour_strain_p95_pct
    # 3. the summary row, stored in the job so a resumed batch can show it without planning again
    row = summary_row(plate, job, strain_pct, warnings, time.perf_counter() - started,
                      time.process_time() - cpu_started)
    job.batch = BatchRecord(key=key, row=row)
    save_job(job, job_path(plate, options))
    return row


def _flat(plate: Plate, options: BatchOptions, design, warnings: list):
    from mppf.geometry.read import read_points
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points

    if plate.flat:
        return read_points(plate.flat, units=options.units).points, None, plate.flat
    unfolding = unfold(design.points, design.faces)
    warnings.extend(unfolding.warnings)
    path = Path(options.out_dir) / f"{plate.name}.flat.csv"
    write_points(path, unfolding.flat, header=f"flat of {Path(plate.design).name}, mm")
    return unfolding.flat, float(unfolding.max_strain_pct), str(path)


def summary_row(plate: Plate, job, strain_pct, warnings, seconds: float, cpu_seconds: float) -> dict:
    """One line of the batch summary for a planned plate (``time_s`` wall clock, ``cpu_s`` CPU of its worker)."""
    sectional, reports = job.sectional, job.reports
    size = (sectional or reports).plate_size_mm
    size = [None, None] if size is None else size
    steps = sectional.n_steps_total if sectional else len(job.steps)
    travel = sectional.max_travel_mm if sectional else reports.max_travel_mm
    if sectional and sectional.warnings:
        warnings = [*warnings, *sectional.warnings]
    if reports.registration is not None and reports.registration.ambiguous_start:
        warnings = [*warnings, "nearly symmetric plate: check which way round it lies"]
    return {"plate": plate.name, "status": "planned", "length_mm": _round(size[0]), "width_mm": _round(size[1]),
            "thickness_mm": plate.thickness_mm, "sections": len(job.sections) if job.sections else 1,
            "steps": int(steps), "max_travel_mm": _round(travel, 1), "strain_pct": _round(strain_pct, 4),
            "border_step_mm": _round(sectional.max_border_step_mm, 3) if sectional else None,
            "warnings": "; ".join(warnings), "reason": "", "time_s": round(seconds, 2),
            "cpu_s": round(cpu_seconds, 2),
            "peak_rss_mb": round(_peak_rss_mb(), 1), "job": f"{plate.name}.job.json"}


def _round(value, digits: int = 0):
    return None if value is None else round(float(value), digits)


def _peak_rss_mb() -> float:
    """Peak resident memory of this process so far (MB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def failed_row(plate: Plate, reason: str, seconds: float = 0.0) -> dict:
    return {"plate": plate.name, "status": "failed", "reason": reason, "time_s": round(seconds, 2),
            "thickness_mm": plate.thickness_mm}


def _task(plate: Plate, options: BatchOptions) -> dict:
    """One plate in a worker: skipped when finished with the same key, a failed row for a bad plate."""
    started = time.perf_counter()
    try:
        key = input_key(plate, options)
        return finished_row(plate, options, key) or plan_plate_files(plate, options, key)
    except MppfError as exc:
        return failed_row(plate, str(exc), time.perf_counter() - started)
    except Exception as exc:  # noqa: BLE001 - a bug on one plate must not stop the batch; named in the row
        return failed_row(plate, f"internal error (a bug in mppf): {type(exc).__name__}: {exc}",
                          time.perf_counter() - started)


def run_batch(plates: list[Plate], options: BatchOptions, reporter=NULL_REPORTER, *, pool=None) -> list[dict]:
    """Plan every plate (skipping finished ones), ``options.workers`` at a time; the rows in the plates' order.

    Each finished plate is reported as a progress line ``[k/n] name: ...``.

    Parameters
    ----------
    plates : list of Plate
    options : BatchOptions
    reporter : Reporter
    pool : concurrent.futures.Executor, optional
        Running workers (:func:`planning_pool`) to plan in instead of a pool of the batch's own
        (then ``options.workers`` is not used).

    Returns
    -------
    list of dict
        One summary row per plate, in the plates' order.
    """
    Path(options.out_dir).mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    reporter.start("planning plates", total=len(plates))

    def done(row: dict) -> None:
        rows[row["plate"]] = row
        reporter.advance()
        reporter.info(f"[{len(rows)}/{len(plates)}] {row['plate']}: {describe(row)}")

    if pool is None and options.workers <= 1:
        for plate in plates:
            done(_task(plate, options))
    elif pool is not None:
        _plan_in(pool, plates, options, done)
    else:
        with planning_pool(options.workers) as own:
            _plan_in(own, plates, options, done)
    reporter.finish()
    return [rows[p.name] for p in plates]


def _plan_in(pool, plates: list[Plate], options: BatchOptions, done) -> None:
    """Each plate a task of the pool; ``done(row)`` as they finish."""
    futures = {pool.submit(_task, plate, options): plate for plate in plates}
    for future in as_completed(futures):
        try:
            done(future.result())
        except Exception as exc:  # noqa: BLE001 - the worker died (memory?): that plate failed
            done(failed_row(futures[future], f"the worker planning it stopped: {type(exc).__name__}: {exc}"))


def describe(row: dict) -> str:
    """A summary row as a short phrase for the progress lines."""
    if row["status"] == "failed":
        return f"FAILED: {row['reason']}"
    text = (f"{row['status']}, {row.get('sections', 1)} section(s), {row.get('steps')} step(s), "
            f"largest travel {row.get('max_travel_mm')} mm")
    return text + (f" in {row['time_s']:.1f} s" if row["status"] == "planned" else "")


def plate_dicts(plates: list[Plate]) -> list[dict]:
    """The plates as plain dicts (for ``--json`` and the benchmark)."""
    return [asdict(p) for p in plates]
