"""Geometry commands: ``mppf fit`` (surface fit of a plate)."""

from __future__ import annotations

import click

from mppf.cli._common import console, print_json, read_input, units_option


def _degree(value: str):
    return value if value == "auto" else int(value)


@click.command("fit")
@click.argument("file", type=click.Path(dir_okay=False, path_type=str))
@click.option("--degree", type=click.Choice(["2", "3", "4", "auto"]), default="3", show_default=True,
              help="Polynomial degree (k, k); 'auto' picks it by held-out residual.")
@click.option("--kind", type=click.Choice(["poly", "spline"]), default="poly", show_default=True,
              help="Polynomial surface (paper eq. 1.1) or smoothing bicubic B-spline.")
@click.option("--smoothing", type=float, default=None,
              help="Spline only: target RMS residual in mm (default: least squares on uniform knots).")
@units_option
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
def fit_command(file: str, degree: str, kind: str, smoothing: float | None, units: str, as_json: bool) -> None:
    """Fit a surface z = D(u, v) to the plate in FILE, in the plate's own frame.

    FILE is a point or mesh file (.csv .txt .xyz .ply .stl .obj). Prints the fit
    residual (RMS and largest), degree, kind, point count and the local frame
    (origin and u, v, n axes in the file's coordinates).
    """
    from mppf.geometry.surface import fit_plate

    cloud = read_input(file, units=units)
    plate = fit_plate(cloud.points, degree=_degree(degree), kind=kind, smoothing=smoothing,
                      faces=cloud.faces, source=str(file))
    surface = plate.surface
    result = {
        "file": str(file),
        "sha256": cloud.sha256,
        "n_points": plate.n_points,
        "kind": plate.kind,
        "degree": plate.degree,
        "rms_mm": plate.rms_mm,
        "max_abs_mm": plate.max_abs_mm,
        "bounds_mm": {"u": list(surface.bounds[0]), "v": list(surface.bounds[1])},
        "frame": plate.frame.to_dict(),
        "tf_local_world": plate.frame.tf_local_world.tolist(),
    }
    if getattr(surface, "heldout_rms_mm", ()):
        result["heldout_rms_mm"] = {str(k): rms for k, rms in surface.heldout_rms_mm}
    if as_json:
        print_json(result)
        return
    _print_fit(result)


def _print_fit(result: dict) -> None:
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=f"fit of {escape(result['file'])}", show_header=False, title_justify="left")
    table.add_column(style="bold")
    table.add_column()
    degree = "bicubic B-spline" if result["kind"] == "spline" else f"polynomial ({result['degree']}, {result['degree']})"
    table.add_row("surface", degree)
    table.add_row("points", str(result["n_points"]))
    table.add_row("residual RMS", f"{result['rms_mm']:.3f} mm")
    table.add_row("residual max", f"{result['max_abs_mm']:.3f} mm")
    if "heldout_rms_mm" in result:
        scores = ", ".join(f"k={k}: {rms:.3f}" for k, rms in result["heldout_rms_mm"].items())
        table.add_row("held-out RMS", f"{scores} mm")
    (u0, u1), (v0, v1) = result["bounds_mm"]["u"], result["bounds_mm"]["v"]
    table.add_row("extent", f"u {u0:.1f} .. {u1:.1f} mm, v {v0:.1f} .. {v1:.1f} mm")
    frame = result["frame"]
    table.add_row("frame origin", _vector(frame["origin"]) + " mm")
    for name, axis in zip("uvn", frame["axes"]):
        table.add_row(f"axis {name}", _vector(axis))
    console.print(table)


def _vector(values) -> str:
    return "(" + ", ".join(f"{x:.4f}" if abs(x) < 10 else f"{x:.2f}" for x in values) + ")"


COMMANDS = [fit_command]
