"""This machine's press: the installed press description, and the check that a press is that one.

The press description itself (:class:`~mppf.model.press.PressConfig`, its TOML loader and writer) is
shared data of every stage and lives in :mod:`mppf.model.press`.
"""

from __future__ import annotations

from mppf.core.errors import ConfigError
from mppf.model.press import PressConfig, example_press_path, load_press


def machine_press(press_path=None, *, dry_run: bool = False) -> tuple[PressConfig, str]:
    """This machine's press description, and how to name it: ``press_path``, else the installed one.

    The installed press is :func:`mppf.core.paths.installed_press_path` (copied there once per
    installation); without one a dry run uses the bundled example press, anything else is
    refused. The press block a job carries is never the machine's press.

    Raises
    ------
    ConfigError
        No press description (not a dry run), or one that cannot be read.
    """
    from mppf.core.paths import installed_press_path

    if press_path is not None:
        return load_press(press_path), str(press_path)
    installed = installed_press_path()
    if installed.exists():
        return load_press(installed), f"the installed press {installed}"
    if dry_run:
        return load_press(example_press_path()), "the example press (dry run, no press installed)"
    raise ConfigError(f"no press description for this machine: no --press given and none installed at {installed}",
                      hint=f"give --press PRESS.toml (this machine's press), or copy it once to {installed}; "
                           "the press block a job carries is never used")


def check_installed_press(press: PressConfig, what: str) -> None:
    """Refuse a press description that is not the installed one of this machine (when one is installed).

    For the commands that take the press from elsewhere (``mppf loop --press``, a plate's
    recorded press on ``--resume``) before they drive a real PLC.

    Raises
    ------
    ConfigError
        Naming the keys that differ and both values.
    """
    from mppf.core.paths import installed_press_path
    from mppf.planning.validate import press_differences

    installed = installed_press_path()
    if not installed.exists():
        return
    machine = load_press(installed)
    if machine != press:
        raise ConfigError(f"{what} is not this machine's press, the installed {installed}: "
                          + "; ".join(press_differences(press, machine, str(installed))[:10]),
                          hint=f"give --press {installed} (this machine's press), or plan the plate for it")
