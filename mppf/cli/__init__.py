"""The ``mppf`` command line: thin wrappers over the library, one error handler.

Each sub-module exports its commands (``COMMANDS``); :data:`COMMAND_MODULES` says which
module holds which command, and a module is imported only when one of its commands runs
(``mppf --help`` imports them all), so ``mppf status`` and ``mppf reset`` start without
numpy, rich or the planning code. A plain ``mppf stop --plc URL [--audit PATH]`` does not even
import click (:mod:`mppf.cli.plc_ops`): STOP leaves at once. :func:`main` maps errors to exit
codes (see :mod:`mppf.core.errors`) and prints one clear message, with a traceback only
under ``--debug``. The click group :data:`cli` is built on first use.
"""

from __future__ import annotations

import importlib
import sys
import traceback

from mppf import __version__
from mppf.cli.plc_ops import stop_arguments, stop_plc
from mppf.core.errors import EXIT_BUG, EXIT_CANCELLED, MppfError

COMMAND_MODULES = {
    "fit": "geometry", "register": "register_cmd", "unfold": "unfold_cmd", "plan": "plan_cmd", "sim": "sim_cmd",
    "press": "press_cmd", "status": "press_cmd", "stop": "press_cmd", "reset": "press_cmd",
    "compare": "compare_cmd", "loop": "loop_cmd", "history": "history_cmd", "demo": "demo_cmd",
    "panel": "panel_cmd", "extract": "extract_cmd",
}
"""Every command of ``mppf`` and the module of :mod:`mppf.cli` that defines it (in its ``COMMANDS``)."""


def _build_cli():
    """The click group of every command (click is imported here, not by ``mppf stop``)."""
    import click

    class LazyGroup(click.Group):
        """A click group that imports a command's module when the command is used or listed."""

        def list_commands(self, ctx: click.Context) -> list[str]:
            return sorted(set(super().list_commands(ctx)) | set(COMMAND_MODULES))

        def get_command(self, ctx: click.Context, name: str):
            if name not in self.commands and name in COMMAND_MODULES:
                module = importlib.import_module(f"mppf.cli.{COMMAND_MODULES[name]}")
                for command in module.COMMANDS:
                    self.add_command(command)
            return super().get_command(ctx, name)

    @click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
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

    return cli


_CLI = []


def _cli():
    """The click group, built once."""
    if not _CLI:
        _CLI.append(_build_cli())
    return _CLI[0]


def __getattr__(name: str):
    if name == "cli":  # ``from mppf.cli import cli`` builds the group
        return _cli()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _err_console():
    """The error console (rich is imported only when there is something to report)."""
    from mppf.cli._common import err_console

    return err_console


def _run_stop(plc_url: str, audit_path: str | None) -> int:
    """``mppf stop`` without click (:mod:`mppf.cli.plc_ops`)."""
    stop_plc(plc_url, audit_path)
    return 0


def _run_click(args: list[str]) -> int:
    """Every other command line: click parses it; its own exits and usage errors become exit codes."""
    import click

    try:
        _cli().main(args=args, prog_name="mppf", standalone_mode=False)
        return 0
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except click.exceptions.Abort:
        _err_console().print("[bold red]cancelled[/]")
        return EXIT_CANCELLED


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return (and exit with) the exit code."""
    args = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in args
    try:
        stop = stop_arguments(args)
        code = _run_stop(*stop) if stop is not None else _run_click(args)
    except KeyboardInterrupt:
        _err_console().print("[bold red]cancelled[/] by the operator")
        code = EXIT_CANCELLED
    except MppfError as exc:
        from rich.markup import escape

        err_console = _err_console()
        if debug:
            traceback.print_exc()
        err_console.print(f"[bold red]error:[/] {escape(exc.message)}", highlight=False, markup=True)
        if exc.hint:
            err_console.print(f"  [yellow]what to do:[/] {escape(exc.hint)}", highlight=False)
        code = exc.exit_code
    except Exception as exc:  # noqa: BLE001 - the last line of defence
        if debug:
            traceback.print_exc()
        _err_console().print(
            f"[bold red]internal error (a bug in mppf):[/] {type(exc).__name__}: {exc}\n"
            "  run again with --debug for the traceback and report it",
            highlight=False,
        )
        code = EXIT_BUG
    if argv is None:
        sys.exit(code)
    return code
