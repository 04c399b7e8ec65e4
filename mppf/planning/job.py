"""The job file on disk: sealed on save, its seal checked by the one loader.

The job itself and its (de)serialisation are shared data of every stage and live in
:mod:`mppf.model.job` (its parts in :mod:`mppf.model.job_parts`, its sections in
:mod:`mppf.model.job_sections`). :func:`save_job` seals the file with the installation's key
(:mod:`mppf.core.seal`) and :func:`load_job` refuses a job whose content does not match its seal,
naming the parts that changed; older, unsealed jobs (versions 1-3) are read only where nothing
is pressed (``require_seal=False``: compare, history, reports).
"""

from __future__ import annotations

from pathlib import Path

from mppf.core.errors import InputError
from mppf.model.job import (
    READ_VERSIONS,
    SEALED_VERSION,
    Job,
    check_format,
    job_from_dict,
    read_job_document,
)
from mppf.model.job_provenance import Seal


def load_job(path, *, require_seal: bool = True) -> Job:
    """Read a job file and check it: the format, numbers where numbers belong, the seal, the rest.

    The one loader of job files (``mppf press``, ``mppf loop``, the panel, batch, ``compare --job``).

    Parameters
    ----------
    path : path-like
    require_seal : bool
        True (what presses or plans from the job): an older, unsealed job (versions 1-3) is
        refused. False (what only reads it: compare, history, reports): an unsealed older job
        is read. A job that carries a seal (every version-4 job must) is refused whenever
        its content does not match it.

    Raises
    ------
    InputError
        Missing or unreadable file, invalid JSON, values that are not numbers, a seal that does
        not match (naming what changed), an unsealed job where one is required, an invalid job.
    """
    source = str(path)
    doc = read_checked_document(path)
    check_seal(doc, source, require_seal=require_seal)
    return job_from_dict(doc, source=source)


def read_checked_document(path) -> dict:
    """The JSON document of a job file, checked in everything but its seal: format, numbers, content.

    The first half of :func:`load_job`; ``mppf reseal`` alone reads a job this way, since it seals
    again a job whose content deliberately no longer matches its seal.

    Raises
    ------
    InputError
        Missing or unreadable file, invalid JSON, another format or version, values that are not
        numbers where numbers belong (:func:`mppf.planning.validate.check_job_document`).
    """
    from mppf.planning.validate import check_job_document

    source = str(path)
    doc = read_job_document(path)
    check_format(doc, source)
    check_job_document(doc, source)
    return doc


def check_seal(doc: dict, source: str, *, require_seal: bool = True) -> None:
    """Refuse a job document whose seal does not match (or that has none where one is required).

    Raises
    ------
    SealError
        See :func:`mppf.core.seal.verify_document`; an unsealed version-1..3 job when ``require_seal``.
    """
    from mppf.core.seal import SEAL_KEY, SealError, verify_document

    if doc.get("version") in READ_VERSIONS and doc["version"] < SEALED_VERSION and SEAL_KEY not in doc:
        if require_seal:
            raise SealError(f"{source}: an older, unsealed job (version {doc['version']}): nothing ties its "
                              "strokes to the plan, so it is not pressed",
                              hint=f"re-plan the plate with 'mppf plan', or check the job and run 'mppf reseal "
                                   f"{source} --reason \"...\" --press PRESS.toml'")
        return
    verify_document(doc, source)


def save_job(job: Job, path, *, sealed_by: str = "mppf plan", reason: str | None = None) -> Path:
    """Seal a job with the installation's key and write it atomically (a temporary file renamed into place).

    The seal (:func:`mppf.core.seal.seal_document`) replaces any the job carried and is kept in
    ``job.seal``, so ``job.sha256()`` is the hash of the file written.

    Parameters
    ----------
    job : Job
    path : path-like
    sealed_by : str
        What sealed it, recorded in the seal (``"mppf plan"``, ``"mppf loop"``, ``"mppf reseal by NAME"``).
    reason : str, optional
        Why (``mppf reseal``).

    Raises
    ------
    InputError
        The file cannot be written, or the seal key cannot be read or made.
    """
    from mppf.core.json_text import indented_json
    from mppf.core.seal import SEAL_KEY, load_key, seal_document

    path = Path(path)
    doc = seal_document(job.to_dict(), load_key(), sealed_by=sealed_by, reason=reason)
    job.seal = Seal.from_doc(doc[SEAL_KEY], f"{path}: seal")
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(indented_json(doc))  # job.to_json(): doc is job.to_dict() with its new seal last
        tmp.replace(path)
    except OSError as exc:
        raise InputError(f"cannot write job file {path}: {exc.strerror}", hint="choose a writable path") from None
    return path
