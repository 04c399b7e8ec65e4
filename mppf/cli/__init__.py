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
    "batch": "batch_cmd", "reseal": "reseal_cmd", "tryout": "tryout_cmd",
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


def _run_click(args: list[str], as_json: bool) -> int:
    """Every other command line: click parses it; its own exits and usage errors become exit codes."""
    import click

    try:
        code = _cli().main(args=args, prog_name="mppf", standalone_mode=False)  # a command's click Exit(code)
        return code if isinstance(code, int) and not isinstance(code, bool) else 0
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        exc.show()
        if getattr(exc, "ctx", None) is None:  # no usage line from click: say where help is
            print(f"  what to do: see 'mppf {args[0] if args else ''} --help'".replace("  --", " --"),
                  file=sys.stderr)
        if as_json:
            _json_error(type(exc).__name__, exc.format_message(), None, exc.exit_code)
        return exc.exit_code
    except click.exceptions.Abort:
        _err_console().print("[bold red]cancelled[/]")
        return EXIT_CANCELLED


def _json_error(kind: str, message: str, hint: str | None, code: int) -> None:
    """``--json`` commands: the error as one JSON object, the last line of stderr (after the readable message)."""
    import json

    print(json.dumps({"error": {"type": kind, "message": message, "hint": hint, "exit_code": code}}),
          file=sys.stderr, flush=True)


def _report(exc: BaseException, as_json: bool, debug: bool) -> int:
    """Print one clear message for ``exc`` (traceback only with ``--debug``); its exit code."""
    if debug:
        traceback.print_exc()
    if isinstance(exc, KeyboardInterrupt):
        kind, message, hint, code = "Cancelled", "cancelled by the operator", None, EXIT_CANCELLED
    elif isinstance(exc, MppfError):
        kind, message, hint, code = type(exc).__name__, exc.message, exc.hint or _default_hint(exc), exc.exit_code
    elif isinstance(exc, OSError) and exc.errno == 36:  # ENAMETOOLONG, from any path a user gave: bad input
        name = str(exc.filename or "")
        kind, message, code = "InputError", (f"the path {name[:60]!r}... ({len(name)} characters) is too long for "
                                             f"this system: {exc.strerror}"), 2
        hint = "give a shorter path (each folder or file name at most 255 bytes, the whole path at most 4096)"
    else:
        kind, message, code = "InternalError", f"{type(exc).__name__}: {exc}", EXIT_BUG
        hint = "a bug in mppf: run again with --debug for the traceback and report it"
    _print_error(exc, message, hint, code)
    if as_json:
        _json_error(kind, message, hint, code)
    return code


def _default_hint(exc: MppfError) -> str | None:
    """What to do, for an error raised without a hint."""
    from mppf.core.errors import ConfigError, FileFormatError, InputError

    if isinstance(exc, (FileFormatError, ConfigError)):
        return "fix or replace the file named above (docs/file-formats.md says what it must hold)"
    if isinstance(exc, InputError):
        return "check the value named above; 'mppf COMMAND --help' lists the options and their ranges"
    return None


def _print_error(exc: BaseException, message: str, hint: str | None, code: int) -> None:
    """The readable message (and what to do) on stderr, user text never read as markup."""
    from rich.markup import escape

    err_console = _err_console()
    if isinstance(exc, KeyboardInterrupt):
        err_console.print("[bold red]cancelled[/] by the operator", highlight=False)
        return
    label = "internal error (a bug in mppf):" if code == EXIT_BUG and not isinstance(exc, MppfError) else "error:"
    err_console.print(f"[bold red]{label}[/] {escape(message)}", highlight=False, soft_wrap=True)
    if hint:
        err_console.print(f"  [yellow]what to do:[/] {escape(hint)}", highlight=False, soft_wrap=True)


def _close_reporters() -> None:
    """End the heartbeat of every progress reporter a command left running."""
    common = sys.modules.get("mppf.cli._common")
    if common is not None:
        common.close_reporters()


BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""Set to 1 by :func:`main` unless the environment says otherwise (see :func:`_one_blas_thread`)."""


def _one_blas_thread() -> None:
    """One BLAS thread for the command, unless its environment names a number (set before numpy is loaded).

    mppf's linear algebra is many small products and banded solves (the plate simulator, the correction's
    model, the registration), where a BLAS thread pool spins instead of working: ``mppf demo`` took 103 s
    with the default pool on a busy 2-core machine against 46 s with one thread (docs/architecture.md). The
    work that runs in parallel does so in processes and threads of its own (``mppf batch``, the registration's
    two start fits). The variables must be set before the BLAS is loaded (scipy's wheels load their own
    OpenBLAS when scipy.linalg first is): a command's process sets them before it imports numpy.
    """
    import os

    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return (and exit with) the exit code.

    Errors print one message (and a hint) on stderr; with ``--json`` the last line of stderr
    is the same error as one JSON object (``{"error": {"type", "message", "hint", "exit_code"}}``).
    Exit codes as :mod:`mppf.core.errors` says.
    """
    _one_blas_thread()
    args = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in args
    as_json = "--json" in args
    try:
        stop = stop_arguments(args)
        code = _run_stop(*stop) if stop is not None else _run_click(args, as_json)
    except (KeyboardInterrupt, Exception) as exc:  # noqa: BLE001 - the one handler, the last line of defence
        code = _report(exc, as_json, debug)
    finally:
        _close_reporters()
    if argv is None:
        sys.exit(code)
    return code
