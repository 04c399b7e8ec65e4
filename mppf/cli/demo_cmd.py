"""``mppf demo``: the whole chain on a bundled hull plate, all simulated (thin over :mod:`mppf.loop.demo`).

A faithful dry run: the simulated PLC in this process, driven over loopback Modbus by the
real driver (:func:`mppf.cli.press_policy.press_link` without a PLC URL); the pictures and
the report come from :func:`mppf.report.convergence.demo_report`.
"""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path

import click

from mppf.cli._common import RichReporter, console, esc
from mppf.cli._cycles import cycle_table, print_cycle
from mppf.cli.press_policy import press_link, time_scale_option
from mppf.loop.demo import DEMO_PLATE, DEMO_SEED, DEMO_THICKNESS_MM


def _check_plate_name(name: str) -> None:
    """Refuse a --plate that is not one of the bundled hull plates."""
    import mppf
    from mppf.core.errors import InputError

    folder = Path(mppf.__file__).parent / "examples" / "hull"
    known = sorted(p.stem for p in folder.glob("*.csv"))
    if name not in known:
        raise InputError(f"--plate: no bundled plate named {name!r}", hint=f"give one of {', '.join(known)}")


@click.command("demo")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("mppf-demo"),
              show_default=True, help="Output folder (pictures, report, history).")
@click.option("--plate", "plate_name", default=DEMO_PLATE, show_default=True,
              help="Bundled hull plate (mppf/examples/hull/NAME.csv).")
@click.option("--seed", type=int, default=DEMO_SEED, show_default=True, help="Seed of the simulated plate and scans.")
@click.option("--thickness", type=float, default=DEMO_THICKNESS_MM, show_default=True, help="Plate thickness (mm).")
@click.option("--physics", type=click.Choice(["fd", "fe"]), default="fd", show_default=True,
              help="Simulated plate: the finite-difference steel plate (fd) or the finite-element plate computed "
                   "by CalculiX (fe, needs ccx; docs/simulator-fe.md).")
@time_scale_option
def demo(out_dir, plate_name, seed, thickness, time_scale, physics):
    """Unfold, plan, press, scan, compare and loop on a bundled hull plate, all simulated.

    A dry run: the simulated PLC runs in this process and is driven over loopback Modbus
    by the real driver; the plate and the scanner are simulated. Writes pictures (strain,
    strokes, deviation per cycle, convergence), an HTML report and the history into
    --out, and prints a summary table.
    """
    from mppf.core.validate import check_number

    # the options checked before anything is imported, computed or written
    check_number("--seed", seed, low=0, integer=True, hint="give a whole number, 0 or more")
    check_number("--thickness", thickness, low=0.0, low_open=True, high=200.0, unit="mm",
                 hint="give the plate thickness in mm, e.g. 20")
    _check_plate_name(plate_name)
    if physics == "fe":
        from mppf.sim.fe.ccx import find_ccx

        find_ccx()  # without CalculiX: how to install it (exit 2)

    from mppf.drivers.audit import AuditLog
    from mppf.loop.demo import run_demo
    from mppf.report.convergence import demo_report

    started = time.monotonic()
    reporter = RichReporter()
    dry_run = f"simulated PLC over loopback Modbus, motion {time_scale:g}x faster than the real press"

    @contextlib.contextmanager
    def connect(press):  # the demo's press: the dry run of mppf press and mppf loop, audited in --out
        with AuditLog(out_dir / "audit.sqlite") as audit, \
                press_link(press, None, audit=audit, time_scale=time_scale, reporter=reporter) as link:
            yield link

    try:
        run = run_demo(out_dir, plate_name=plate_name, seed=seed, thickness_mm=thickness, connect=connect,
                       reporter=reporter, on_cycle=print_cycle, physics=physics)
        files = demo_report(run, intro=(
            f"Dry run of mppf demo on the bundled hull plate {plate_name}, {thickness:g} mm, seed {seed}: "
            f"{dry_run} (the real driver), simulated plate (true material scattered around the nominal) "
            "and simulated scanner."))
    finally:
        reporter.finish()
    result = run.result
    console.print(cycle_table(result.cycles, f"demo plate {esc(plate_name)} ({thickness:g} mm, seed {seed}): "
                                             f"{result.status}"))
    console.print(f"dry run: {dry_run}", soft_wrap=True)
    console.print(f"pictures and report in {out_dir}{os.sep}:", soft_wrap=True, markup=False)
    for path in files:
        console.print(f"  {path}", soft_wrap=True, markup=False)
    console.print(f"done in {time.monotonic() - started:.1f} s")


COMMANDS = [demo]
