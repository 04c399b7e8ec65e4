"""``mppf extract``: cut a plate out of a hull model (IGES / STEP) and write it as points or a mesh."""

from __future__ import annotations

import time
from pathlib import Path

import click

from mppf.cli._common import check_output_path, console, print_json, scale_option

POINT_SUFFIXES = (".csv", ".txt", ".xyz", ".ply")
MESH_SUFFIXES = (".stl", ".obj")


@click.command("extract")
@click.argument("hull", type=click.Path(dir_okay=False, path_type=str))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=str),
              help="Plate file to write: .csv .txt .xyz (grid points, row by row), .ply (points and "
                   "triangles), .stl .obj (the grid as a mesh).")
@scale_option
@click.option("--polygon", default=None,
              help="The plate's outline seen along an axis, corners in full-scale hull mm: 'X,Z X,Z ...' "
                   "(for --seen-from +y; Y,Z for x, X,Y for z).")
@click.option("--seen-from", "seen_from", default="+y", show_default=True,
              help="With --polygon: the axis and side the plate is seen from (+y side shell, -z bottom, +x/-x).")
@click.option("--x", "x_mm", type=float, nargs=2, default=None, metavar="X0 X1",
              help="The plate's butts: from station X0 to X1 (mm, hull x at full scale).")
@click.option("--girth", "girth_mm", type=float, nargs=2, default=None, metavar="G0 G1",
              help="The plate's seams: girth from the keel, along the section, G0 to G1 (mm at full scale).")
@click.option("--spacing", "spacing_mm", type=click.FloatRange(min=0.0, min_open=True), default=50.0,
              show_default=True, help="Grid spacing (mm at full scale).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def extract_command(hull: str, output: str, scale: float, polygon: str | None, seen_from: str,
                    x_mm, girth_mm, spacing_mm: float, as_json: bool) -> None:
    """Cut the plate given by its region out of the hull model HULL (.igs .iges .stp .step).

    The region is in hull coordinates (mm at full scale: --scale 31.6 reads a 1:31.6 model):
    either --polygon with --seen-from (the plate as drawn on the profile or body plan), or
    --x with --girth (butts and seams on the shell expansion, girth from the keel). The
    plate is sampled on a grid at --spacing, every point on the exact CAD surface; the
    grid's triangles go to .ply .stl .obj. Prints the size, area and the triangles' largest
    distance from the surface.
    """
    from mppf.geometry.cad import CadModel
    from mppf.geometry.extract import extract_plate

    out = check_output_path(output, "the plate file", POINT_SUFFIXES + MESH_SUFFIXES, kind="plate file")
    region = _region(polygon, seen_from, x_mm, girth_mm)
    start = time.perf_counter()
    with CadModel(hull, scale=scale) as model:
        read_s = time.perf_counter() - start
        plate = extract_plate(model, region, spacing_mm)
        n_faces = len(model.faces)
    _write(out, plate, hull)
    report = {
        "hull": str(hull), "output": str(out), "scale": scale, "n_surfaces": n_faces,
        "region": _region_dict(region), "spacing_mm": spacing_mm,
        "n_points": int(plate.points.shape[0]), "grid_shape": list(plate.grid_shape),
        "n_triangles": int(plate.faces.shape[0]), "size_mm": plate.size_mm.tolist(),
        "area_m2": plate.area_mm2 / 1e6, "chord_mm": plate.chord_mm,
        "read_s": read_s, "total_s": time.perf_counter() - start,
    }
    if as_json:
        print_json(report)
        return
    _print_report(report)


def _region(polygon, seen_from, x_mm, girth_mm):
    import numpy as np

    from mppf.core.errors import InputError
    from mppf.geometry.extract import GirthRegion, ProjectedRegion

    if (polygon is None) == (x_mm is None and girth_mm is None):
        raise InputError("give the plate's region either as --polygon or as --x and --girth",
                         hint="e.g. --x 113500 116500 --girth 14250 16250, or --polygon '113500,400 116500,400 ...'")
    if polygon is None:
        if x_mm is None or girth_mm is None:
            raise InputError("--x and --girth go together", hint="give both: --x X0 X1 --girth G0 G1 (mm)")
        return GirthRegion(tuple(x_mm), tuple(girth_mm))
    try:
        corners = [[float(v) for v in pair.split(",")] for pair in polygon.replace(";", " ").split()]
        array = np.asarray(corners, dtype=float)
    except ValueError:
        array = np.empty((0,))
    if array.ndim != 2 or array.shape[1] != 2 or array.shape[0] < 3:
        raise InputError(f"--polygon must be at least 3 corners 'A,B A,B A,B', got {polygon!r}",
                         hint="give the corners in mm, a comma inside each corner, spaces between them")
    return ProjectedRegion(array, seen_from)


def _region_dict(region) -> dict:
    from mppf.geometry.extract import GirthRegion

    if isinstance(region, GirthRegion):
        return {"x_mm": list(region.x_mm), "girth_mm": list(region.girth_mm)}
    return {"polygon_mm": region.polygon_mm.tolist(), "seen_from": region.seen_from}


def _write(out: Path, plate, hull: str) -> None:
    from mppf.core.errors import InputError
    from mppf.geometry.write import write_points

    suffix = out.suffix.lower()
    if suffix in MESH_SUFFIXES:
        import trimesh

        try:
            trimesh.Trimesh(plate.points, plate.faces, process=False).export(str(out))
        except OSError as exc:
            raise InputError(f"cannot write {out}: {exc.strerror or exc}", hint="check the folder") from None
        return
    rows, cols = plate.grid_shape
    header = (f"x_mm,y_mm,z_mm  plate cut from {Path(hull).name}: grid {rows} x {cols}, row by row"
              + ("" if plate.points.shape[0] == rows * cols
                 else f" ({plate.points.shape[0]} points inside the region)"))
    write_points(out, plate.points, header=header, faces=plate.faces if suffix == ".ply" else None)


def _print_report(report: dict) -> None:
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=f"plate cut from {escape(report['hull'])}", show_header=False, title_justify="left")
    table.add_column(style="bold")
    table.add_column()
    table.add_row("hull model", f"{report['n_surfaces']} surfaces, scale {report['scale']:g}, "
                                f"read in {report['read_s']:.2f} s")
    rows, cols = report["grid_shape"]
    table.add_row("grid", f"{rows} x {cols} at {report['spacing_mm']:g} mm, {report['n_points']} points, "
                          f"{report['n_triangles']} triangles")
    length, width = report["size_mm"]
    table.add_row("plate", f"{length:.1f} x {width:.1f} mm on the surface, {report['area_m2']:.3f} m2")
    table.add_row("triangles from the surface", f"at most {report['chord_mm']:.3f} mm")
    table.add_row("plate file", escape(report["output"]))
    console.print(table)


COMMANDS = [extract_command]
