"""``mppf register``: rigid registration of two point files (paired or ICP)."""

from __future__ import annotations

import click

from mppf.cli._common import RichReporter, check_output_path, console, err_console, print_json, units_option
from mppf.core.errors import MppfError


@click.command("register")
@click.argument("source", type=click.Path(dir_okay=False, path_type=str))
@click.argument("target", type=click.Path(dir_okay=False, path_type=str))
@click.option("--method", type=click.Choice(["paired", "point", "plane"]), default="point", show_default=True,
              help="paired: known point pairs (same order, same count), closed form; "
                   "point / plane: ICP point-to-point (the paper) or point-to-plane.")
@click.option("--init", "init", type=click.Choice(["principal", "identity"]), default="principal",
              show_default=True, help="ICP start: principal axes and centroids, or as the files are.")
@click.option("--robust", type=click.Choice(["none", "huber", "tukey"]), default="none", show_default=True,
              help="Robust pair weights for scans with outliers and partial overlap.")
@click.option("--trim", "trim_fraction", type=float, default=None,
              help="Drop this fraction of the worst pairs each iteration (e.g. 0.1).")
@click.option("--max-iterations", type=int, default=100, show_default=True, help="ICP iteration limit per stage.")
@click.option("--pin-outline", type=click.Choice(["auto", "yes", "no"]), default="auto", show_default=True,
              help="Pin the in-plane position with the outline (auto: when both files cover the same plate).")
@units_option
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write the source points moved into the target's coordinates (.csv .txt .xyz .ply).")
def register_command(source: str, target: str, method: str, init: str, robust: str,
                     trim_fraction: float | None, max_iterations: int, pin_outline: str, units: str,
                     as_json: bool, output: str | None) -> None:
    """Register SOURCE onto TARGET: the transform that maps SOURCE into TARGET coordinates.

    Prints the RMS residual, iterations, whether it converged and why it stopped, the
    inlier fraction and the 4x4 transform. With --method paired the files must hold
    the same number of points, in corresponding order.
    """

    from mppf.core.errors import InputError
    from mppf.core.transform import apply_tf
    from mppf.geometry.read import read_points
    from mppf.geometry.write import WRITE_SUFFIXES, write_points
    from mppf.registration.register import register_icp, register_paired
    from mppf.registration.settings import RegisterOptions

    if method == "paired":
        ctx = click.get_current_context()
        icp_only = [f"--{name.replace('_', '-')}" for name in
                    ("init", "robust", "trim_fraction", "max_iterations", "pin_outline")
                    if ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT]
        if icp_only:
            names = ", ".join(icp_only).replace("--trim-fraction", "--trim")
            raise InputError(f"{names} only appl{'ies' if len(icp_only) == 1 else 'y'} to ICP, "
                             "not to --method paired",
                             hint="leave it out, or use --method point or plane")
    if output is not None:  # refuse before the registration, not after it
        check_output_path(output, "the moved points (-o)", WRITE_SUFFIXES, kind="point file")
    src = read_points(source, units=units)
    tgt = read_points(target, units=units)
    if method != "paired":
        from mppf.registration.register import check_icp_points

        for path, cloud in ((source, src), (target, tgt)):
            check_icp_points(cloud.n_points, path)
    try:
        if method == "paired":
            result = register_paired(src.points, tgt.points)
        else:
            options = RegisterOptions(method=method, init=init, max_iterations=max_iterations,
                                      robust=None if robust == "none" else robust, trim_fraction=trim_fraction,
                                      pin_outline={"auto": "auto", "yes": True, "no": False}[pin_outline])
            result = register_icp(src.points, tgt.points, options, reporter=RichReporter(enabled=not as_json))
    except MppfError as exc:
        _name_the_file(exc, source, target)
        raise
    if output is not None:
        write_points(output, apply_tf(result.tf, src.points),
                     header=f"{source} registered onto {target} (mm)")
    if as_json:
        data = result.to_dict()
        data.update({"source": source, "target": target, "n_source": src.n_points, "n_target": tgt.n_points})
        if output is not None:
            data["output"] = output
        print_json(data)
        return
    _print_result(result, source, target, output)


def _name_the_file(exc: MppfError, source: str, target: str) -> None:
    """Put the file name in place of the library's "source: " / "target: " message prefix."""
    for role, path in (("source", source), ("target", target)):
        prefix = f"{role}: "
        if exc.message.startswith(prefix):
            exc.message = f"{path} ({role}): {exc.message[len(prefix):]}"
            exc.args = (exc.message,)
            return


def _print_result(result, source: str, target: str, output: str | None) -> None:
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=f"register {escape(source)} -> {escape(target)}", show_header=False, title_justify="left")
    table.add_column(style="bold")
    table.add_column()
    table.add_row("method", result.method)
    table.add_row("RMS", f"{result.rms_mm:.4f} mm")
    table.add_row("iterations", str(result.iterations))
    state = "[green]converged[/]" if result.converged else "[red]not converged[/]"
    table.add_row("stop", f"{state}: {escape(result.stop_reason)}")
    table.add_row("judgement", escape(result.judgement or ("converged" if result.converged else "failed")))
    if result.method != "paired":
        table.add_row("residual / noise floor", f"{result.residual_mm:.3g} mm / {result.noise_mm:.3g} mm")
        names = result.init.get("candidates") or []
        scores = result.init.get("scores_mm") or []
        tried = ", ".join(f"{n} {s:.3g} mm" for n, s in zip(names, scores)) or str(result.init.get("kind", "-"))
        table.add_row("starts tried", escape(tried))
    table.add_row("inlier fraction", f"{result.inlier_fraction:.3f}")
    if result.method != "paired":
        table.add_row("outline pinned", "yes" if result.outline_pinned else "no")
        unc = result.uncertainty
        parts = [f"{key.rsplit('_', 1)[0]} {_fmt(unc.get(key))}" for key in
                 ("t_u_mm", "t_v_mm", "t_n_mm")]
        table.add_row("1-sigma shift (mm)", ", ".join(parts) + f"  [{unc.get('in_plane', '')}]")
        parts = [f"{key.rsplit('_', 1)[0]} {_fmt(unc.get(key))}" for key in ("r_u_deg", "r_v_deg", "r_n_deg")]
        table.add_row("1-sigma turn (deg)", ", ".join(parts))
    console.print(table)
    matrix = Table(title="transform (source -> target, mm)", show_header=False, title_justify="left")
    for _ in range(4):
        matrix.add_column(justify="right")
    for row in result.tf:
        matrix.add_row(*(f"{v:.6f}" for v in row))
    console.print(matrix)
    if result.ambiguous_start:
        err_console.print("[yellow]warning:[/] the principal-axes start was ambiguous (nearly symmetric "
                          "plate); check the turn of the result")
    for note in result.notes:
        err_console.print(f"[yellow]note:[/] {escape(note)}")
    if output is not None:
        console.print(f"moved source written to {escape(output)}")


def _fmt(value) -> str:
    return "free" if value is None else f"{value:.3g}"


COMMANDS = [register_command]
