"""``mppf reseal``: a deliberate change of a job, checked in full against this machine's press and sealed again.

A job is sealed when it is planned (:mod:`mppf.core.seal`); ``mppf press``, ``mppf loop`` and
the panel refuse one whose content no longer matches its seal, and older unsealed jobs. When a
change is deliberate (a planner's correction, an older job checked by hand), ``mppf reseal``
runs every check of the job validator against the machine's press (``--press``, else the
installed one) and the plan's own consistency, then seals it with this installation's key and
records who (the user name) and why (``--reason``) in the audit log, with what changed since
the old seal where that can be told.
"""

from __future__ import annotations

from pathlib import Path

import click

from mppf.core.errors import ConfigError, InputError, LimitError

MAX_REASON_CHARS = 500


def _check_reason(reason: str) -> str:
    text = (reason or "").strip()
    if not text:
        raise InputError("--reason is empty: a reseal records why the job was changed",
                         hint='give e.g. --reason "strokes of row 3 lowered 1 mm after the trial plate"')
    control = any(ord(ch) < 32 or ord(ch) == 127 for ch in text)
    if len(text) > MAX_REASON_CHARS or control:
        raise InputError(f"--reason must be one line of at most {MAX_REASON_CHARS} characters, got "
                         f"{len(text)} character(s){' with control characters' if control else ''}",
                         hint="say briefly why the job was changed")
    return text


def _user() -> str:
    """The user name recorded with a reseal (the audit log records the same)."""
    import getpass
    import os

    try:
        return getpass.getuser()
    except (KeyError, OSError):  # no passwd entry, e.g. in a container
        return str(os.getuid()) if hasattr(os, "getuid") else "?"


def _previous_seal(doc: dict) -> tuple[str, list[str]]:
    """How the job was sealed before and what changed since (empty when that cannot be told)."""
    from mppf.core.seal import SEAL_KEY, changed_parts, key_id, load_key

    seal = doc.get(SEAL_KEY)
    if not isinstance(seal, dict):
        return "unsealed", []
    key = load_key()
    if seal.get("key_id") != key_id(key):
        return f"sealed by another installation (key {seal.get('key_id')!r})", []
    return f"sealed by {seal.get('sealed_by', '?')}", changed_parts(doc, key)


@click.command("reseal")
@click.argument("job_path", metavar="JOB.json", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--reason", required=True,
              help="Why the job was changed (recorded in the audit log with your user name).")
@click.option("--press", "press_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="This machine's press description (default: the installed $MPPF_HOME/press.toml).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the resealed job here (default: over JOB.json).")
@click.option("--audit", "audit_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Audit log (SQLite). Default: $MPPF_HOME/audit.sqlite.")
def reseal_command(job_path, reason, press_path, output, audit_path):
    """Check a deliberately changed (or older, unsealed) job in full and seal it again.

    Every check of the job validator runs against this machine's press (the job's own
    press block must equal it) and the plan's placements are re-derived; only then is the
    job sealed with this installation's key. The audit log records the user, the reason,
    the old and new SHA-256 and what changed since the old seal.

    Exit codes: 0 resealed, 2 the job fails a check (nothing written) or bad input.
    """
    from mppf.cli._common import check_db_path
    from mppf.cli.plc_ops import open_audit
    from mppf.model.job import job_from_dict
    from mppf.planning.job import read_checked_document, save_job
    from mppf.planning.press import machine_press
    from mppf.planning.validate import validate_job

    reason = _check_reason(reason)
    if audit_path is not None:
        check_db_path(audit_path, "the audit log", "--audit")
    source = str(job_path)
    doc = read_checked_document(job_path)  # checked in full but for the seal: the seal is what is renewed
    before, changed = _previous_seal(doc)
    job = job_from_dict(doc, source=source)
    press, press_source = machine_press(press_path)
    try:
        validate_job(job, press_file=press, press_source=press_source)
    except (ConfigError, LimitError) as exc:
        raise type(exc)(f"job {job_path}: {exc.message}; it was not resealed", hint=exc.hint) from None
    old_sha, user = job.sha256(), _user()
    out = Path(output or job_path)
    with open_audit(audit_path) as audit:
        # sealed beside its place, recorded in the audit log, and only then put in place: no reseal unrecorded
        staged = save_job(job, out.with_name(out.name + ".reseal"), sealed_by=f"mppf reseal by {user}", reason=reason)
        audit.record("-", "reseal", "ok", job_sha256=job.sha256(),
                     detail=(f"{out}: {reason} | was {before}, sha256 {old_sha[:16]} | changed: "
                             f"{', '.join(changed) or 'nothing the old seal can tell'} | press {press_source}")[:2000])
        if audit.unwritten:
            staged.unlink(missing_ok=True)
            raise InputError(f"cannot write the audit log {audit.path}: {out} was not resealed",
                             hint="free space for the audit log (or give a writable --audit), then run again")
        staged.replace(out)
    click.echo(f"resealed {out} for {press_source} by {user}: {reason}")
    click.echo(f"  was {before}; changed since: {', '.join(changed) or 'nothing the old seal can tell'}")
    click.echo(f"  sha256 {job.sha256()}")


COMMANDS: list = [reseal_command]
