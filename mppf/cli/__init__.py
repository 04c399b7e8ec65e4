"""The ``mppf`` command line: thin wrappers over the library, one error handler.

Each sub-module registers its commands; :func:`main` maps errors to exit codes
(see :mod:`mppf.core.errors`) and prints one clear message, with a traceback only under
``--debug``.
"""

from __future__ import annotations

import sys
import traceback

import click
from rich.markup import escape

from mppf import __version__
from mppf.cli._common import err_console
from mppf.core.errors import EXIT_BUG, EXIT_CANCELLED, MppfError


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="mppf")
@click.option("--debug", is_flag=True, help="Show full tracebacks on errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """mppf: multi-point press forming of ship-hull plates.

    Typical shop-floor sequence: unfold the design, plan the strokes, dry-run the job
    on the simulated press, drive the real press, scan, compare, and loop until the
    plate is in tolerance. Lengths are millimetres unless an option says otherwise.
    """
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


def _register_commands() -> None:
    from mppf.cli import (
        compare_cmd,
        demo_cmd,
        geometry,
        history_cmd,
        loop_cmd,
        plan_cmd,
        press_cmd,
        register_cmd,
        sim_cmd,
        unfold_cmd,
    )

    for module in (geometry, register_cmd, unfold_cmd, plan_cmd, sim_cmd, press_cmd, compare_cmd, loop_cmd,
                   history_cmd, demo_cmd):
        for command in module.COMMANDS:
            cli.add_command(command)


_register_commands()


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return (and exit with) the exit code."""
    args = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in args
    try:
        cli.main(args=args, prog_name="mppf", standalone_mode=False)
        code = 0
    except click.exceptions.Exit as exc:
        code = exc.exit_code
    except click.ClickException as exc:
        exc.show()
        code = exc.exit_code
    except click.exceptions.Abort:
        err_console.print("[bold red]cancelled[/]")
        code = EXIT_CANCELLED
    except KeyboardInterrupt:
        err_console.print("[bold red]cancelled[/] by the operator")
        code = EXIT_CANCELLED
    except MppfError as exc:
        if debug:
            traceback.print_exc()
        err_console.print(f"[bold red]error:[/] {escape(exc.message)}", highlight=False, markup=True)
        if exc.hint:
            err_console.print(f"  [yellow]what to do:[/] {escape(exc.hint)}", highlight=False)
        code = exc.exit_code
    except Exception as exc:  # noqa: BLE001 - the last line of defence
        if debug:
            traceback.print_exc()
        err_console.print(
            f"[bold red]internal error (a bug in mppf):[/] {type(exc).__name__}: {exc}\n"
            "  run again with --debug for the traceback and report it",
            highlight=False,
        )
        code = EXIT_BUG
    if argv is None:
        sys.exit(code)
    return code
