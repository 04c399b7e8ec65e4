"""The top-level ``mppf`` command: exit codes, --debug, --version, usage errors."""

from __future__ import annotations

import os
import subprocess
import sys

import click
import pytest

import mppf
from mppf.cli import cli, main
from mppf.core.errors import EXIT_BUG, EXIT_INPUT, EXIT_LINK, EXIT_PRESS, PlcError, PressRefused


@pytest.fixture()
def failing_commands():
    """Extra commands on the real group: refused by the press, refused by the PLC, a bug."""

    @click.command("qa-refused")
    def refused():
        raise PressRefused("the PLC refused GO: punch 3 not homed", hint="home the punches, then retry")

    @click.command("qa-bug")
    def bug():
        return {}["missing key"]

    @click.command("qa-plc-refused")
    def plc_refused():
        raise PlcError("the PLC at tcp://press:502?unit=1 refused writing 2 registers at 100: Modbus exception 3")

    cli.add_command(refused)
    cli.add_command(bug)
    cli.add_command(plc_refused)
    yield
    del cli.commands["qa-refused"]
    del cli.commands["qa-bug"]
    del cli.commands["qa-plc-refused"]


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"mppf, version {mppf.__version__}"


def test_help_lists_the_geometry_commands(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "fit" in out and "register" in out and "--debug" in out


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["no-such-command"], "No such command"),
        (["fit"], "Missing argument"),
        (["fit", "a.csv", "--degree", "7"], "--degree"),
        (["register", "a.csv"], "Missing argument"),
        (["register", "a.csv", "b.csv", "--method", "magic"], "--method"),
        (["register", "a.csv", "b.csv", "--max-iterations", "many"], "--max-iterations"),
        (["fit", "a.csv", "--no-such-option"], "No such option"),
    ],
)
def test_usage_errors_exit_2(args, words, capsys):
    assert main(args) == EXIT_INPUT
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_input_error_exit_2_without_traceback_unless_debug(tmp_path, capsys):
    missing = str(tmp_path / "gone.csv")
    assert main(["fit", missing]) == EXIT_INPUT
    err = capsys.readouterr().err
    assert "gone.csv: file not found" in " ".join(err.split()) and "Traceback" not in err
    assert main(["--debug", "fit", missing]) == EXIT_INPUT
    err = capsys.readouterr().err
    assert "Traceback" in err and "FileFormatError" in err and "file not found" in err


def test_link_failure_exit_3(capsys):
    # port 1 on this machine: nothing listens, the connection is refused at once
    assert main(["status", "--plc", "tcp://127.0.0.1:1?unit=1"]) == EXIT_LINK
    err = capsys.readouterr().err
    assert "cannot connect" in err and "Traceback" not in err


def test_press_refusal_exit_4(failing_commands, capsys):
    assert main(["qa-refused"]) == EXIT_PRESS
    err = " ".join(capsys.readouterr().err.split())
    assert "refused GO: punch 3 not homed" in err and "home the punches" in err


def test_a_plc_refusal_is_exit_4_not_a_link_failure(failing_commands, capsys):
    assert main(["qa-plc-refused"]) == EXIT_PRESS
    assert "Modbus exception 3" in " ".join(capsys.readouterr().err.split())


def test_bug_exit_1_with_traceback_only_under_debug(failing_commands, capsys):
    assert main(["qa-bug"]) == EXIT_BUG
    err = capsys.readouterr().err
    assert "internal error" in err and "KeyError" in err and "Traceback" not in err
    assert main(["--debug", "qa-bug"]) == EXIT_BUG
    assert "Traceback" in capsys.readouterr().err


def test_console_script_exit_code_and_stderr(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "mppf", "register", str(tmp_path / "a.csv"),
                           str(tmp_path / "b.csv")], capture_output=True, text=True, timeout=60)
    assert proc.returncode == EXIT_INPUT
    assert "a.csv: file not found" in " ".join(proc.stderr.split())
    assert "Traceback" not in proc.stderr and proc.stdout == ""


def test_every_command_is_registered_lazily_and_listed_in_the_help(capsys):
    import importlib

    from mppf.cli import COMMAND_MODULES

    defined = {}
    for module in sorted(set(COMMAND_MODULES.values())):
        for command in importlib.import_module(f"mppf.cli.{module}").COMMANDS:
            defined[command.name] = module
    assert defined == COMMAND_MODULES  # the table names every command of every module, and only those
    assert main(["--help"]) == 0
    listed = {line.split()[0] for line in capsys.readouterr().out.split("Commands:")[1].splitlines() if line.strip()}
    assert listed == set(COMMAND_MODULES)


def test_stop_status_and_reset_import_neither_numpy_nor_rich_nor_the_planner(tmp_path):
    """The light commands start fast: ``mppf stop`` has to leave at once."""
    from mppf.sim.plc.host import run_simulated_plc

    with run_simulated_plc(watchdog_s=None) as sim:
        script = ("import sys; from mppf.cli import main; "
                  f"codes = [main([c, '--plc', {sim.url!r}]) for c in ('status', 'stop', 'reset')]; "
                  "print(*codes, *(m in sys.modules for m in ('numpy', 'rich', 'mppf.planning.press', "
                  "'mppf.drivers.plc_press')))")
        proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60,
                              env={**os.environ, "MPPF_HOME": str(tmp_path)})
        assert sim.state() == "IDLE"  # stopped, then reset by the third command
    assert proc.stdout.split()[-7:] == ["0", "0", "0", "False", "False", "False", "False"], proc.stdout + proc.stderr


@pytest.mark.parametrize("args, expected", [
    (["stop", "--plc", "tcp://h:1"], ("tcp://h:1", None)),
    (["stop", "--audit=a.sqlite", "--plc=tcp://h:1"], ("tcp://h:1", "a.sqlite")),
    (["stop"], None),  # click reports the missing --plc
    (["stop", "--plc", "tcp://h:1", "--help"], None),
    (["stop", "--plc", "tcp://h:1", "--plc", "tcp://h:2"], None),
    (["stop", "--plc", "--audit", "x"], None),
    (["--debug", "stop", "--plc", "tcp://h:1"], None),
    (["status", "--plc", "tcp://h:1"], None),
])
def test_only_a_plain_stop_takes_the_path_without_click(args, expected):
    from mppf.cli.plc_ops import stop_arguments

    assert stop_arguments(args) == expected


def test_a_plain_stop_does_not_import_click_and_says_what_the_plc_did(tmp_path):
    from mppf.sim.plc.host import run_simulated_plc

    with run_simulated_plc(watchdog_s=None) as sim:
        script = (f"import sys; from mppf.cli import main; code = main(['stop', '--plc', {sim.url!r}]); "
                  "print(code, 'click' in sys.modules, 'pymodbus' in sys.modules)")
        proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60,
                              env={**os.environ, "MPPF_HOME": str(tmp_path)})
        assert sim.state() == "STOPPED"
    assert "the PLC took it (state STOPPED)" in proc.stdout
    # click and rich stay out; over TCP even pymodbus does (STOP on a bare socket: mppf.drivers.fast_stop)
    assert proc.stdout.split()[-3:] == ["0", "False", "False"], proc.stdout + proc.stderr


@pytest.mark.parametrize("given, expected", [(None, 1), ("2", 2)])
def test_a_command_runs_on_one_blas_thread_unless_the_environment_names_a_number(given, expected):
    # numpy's and scipy's own OpenBLAS, both loaded after main() set the variable (scipy's only with scipy.linalg)
    code = ("import sys; from mppf.cli import main; main(['--version']); import numpy, scipy.linalg; "
            "from threadpoolctl import threadpool_info; "
            "print(sorted({i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'}))")
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                                            "OMP_NUM_THREADS")}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert out.strip().splitlines()[-1] == str([expected]), out
