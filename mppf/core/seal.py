"""The seal of a job file: a keyed hash (HMAC-SHA256) of its content, made when it is planned.

A job file is the contract between the planner and the press: strokes edited by hand, a
section's placement shifted, a step deleted or duplicated, a press block with raised limits
must never reach the press. :func:`seal_document` adds a ``"seal"`` block to a job document;
:func:`verify_document` refuses a document whose content does not match it. The key is the
installation's own (:func:`mppf.core.paths.seal_key_path`: 32 random bytes made on first use,
mode 0600), never in the job, so a job edited anywhere (or planned by another installation)
cannot be made to match without it; a deliberate change goes through ``mppf reseal``.

The seal holds one HMAC per part of the job (:func:`document_parts`: the press, the
thickness, each step, each section's placement and steps, the plate, the material, the inputs'
hashes, ...) so that a refusal names what changed, and one HMAC over the whole document
(``"mac"``, covering the parts too). Numbers are hashed as floats in ``repr`` form, so a JSON
tool that writes ``20.0`` as ``20`` does not break the seal; any other change does.
See ``docs/file-formats.md`` ("The seal").
"""

from __future__ import annotations

import hashlib
import hmac
import json
import math
import os
import secrets
import tempfile
from pathlib import Path

from mppf.core.errors import ConfigError


class SealError(ConfigError):
    """A job whose seal does not match its content, is missing, or was made by another installation (exit 2)."""


ALGORITHM = "HMAC-SHA256"
KEY_BYTES = 32
MAX_KEY_FILE_BYTES = 4096
SEAL_KEY = "seal"
"""The key of the seal block in a job document."""


# ----------------------------------------------------------------------- key ---
def load_key(path: Path | None = None, *, create: bool = True) -> bytes:
    """The installation's seal key (32 bytes), made on first use (mode 0600, never overwritten).

    Parameters
    ----------
    path : Path, optional
        The key file; default :func:`mppf.core.paths.seal_key_path`.
    create : bool
        Make the key when there is none (False: ConfigError).

    Raises
    ------
    ConfigError
        The key file cannot be read or made, or is not a key.
    """
    from mppf.core.paths import seal_key_path

    path = Path(path) if path is not None else seal_key_path()
    if not path.exists() and create:
        _make_key(path)
    try:
        if path.stat().st_size > MAX_KEY_FILE_BYTES:
            raise ValueError("too large")
        key = bytes.fromhex(path.read_text().strip())
    except FileNotFoundError:
        raise ConfigError(f"the seal key {path} does not exist",
                          hint="plan the job on this installation ('mppf plan') or reseal it ('mppf reseal')") from None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise ConfigError(f"the seal key {path} cannot be read as a key ({exc})",
                          hint="restore the key file from the installation's backup, or remove it and reseal "
                               "every job with 'mppf reseal'") from None
    if len(key) != KEY_BYTES:
        raise ConfigError(f"the seal key {path} holds {len(key)} bytes, not {KEY_BYTES}",
                          hint="restore the key file from the installation's backup")
    return key


def _make_key(path: Path) -> None:
    """Write a new random key to ``path`` atomically; a key made meanwhile by another process is kept."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".seal-key-")
        try:
            os.fchmod(fd, 0o600)
            os.write(fd, (secrets.token_hex(KEY_BYTES) + "\n").encode())
            os.fsync(fd)
        finally:
            os.close(fd)
        try:
            os.link(tmp, path)  # atomic, and never replaces a key another process made first
        except FileExistsError:
            pass
        finally:
            os.unlink(tmp)
    except OSError as exc:
        raise ConfigError(f"cannot make the seal key {path}: {exc.strerror or exc}",
                          hint="set MPPF_HOME to a writable folder (the installation's data folder)") from None


def key_id(key: bytes) -> str:
    """A short public name of a key (16 hex digits of its SHA-256), to tell installations apart."""
    return hashlib.sha256(key).hexdigest()[:16]


# ----------------------------------------------------------------- the parts ---
def canonical(value) -> bytes:
    """The bytes hashed for a JSON value: sorted keys, numbers as floats, no spaces.

    Raises
    ------
    ValueError
        NaN or infinite numbers (a job never holds them).
    """
    return _Canonical().text(value).encode()


def _reference_canonical(value) -> str:
    """The canonical text by definition: the value normalised (:func:`_normal`), then ``json.dumps``.

    :class:`_Canonical` gives the same text faster; it falls back to this for anything unusual.
    """
    return json.dumps(_normal(value), sort_keys=True, separators=(",", ":"), allow_nan=False)


def _normal(value):
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        number = float(value)
        if not math.isfinite(number):
            raise ValueError(f"the number {value} is not finite")
        return number
    if isinstance(value, dict):
        return {str(k): _normal(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_normal(v) for v in value]
    raise ValueError(f"a {type(value).__name__} is not a JSON value")


_PLAIN = frozenset({float, str, bool, type(None)})
"""Types the JSON encoder writes exactly as the canonical form does (floats by ``repr``)."""
_DUMPS = json.JSONEncoder(sort_keys=True, separators=(",", ":"), allow_nan=False).encode
_SCALARS = {True: "true", False: "false", None: "null"}


class _Canonical:
    """The canonical text of JSON values, each list and object encoded once (remembered by identity).

    One instance serves one seal or check, so the parts, the content and the whole job (which
    share their lists and objects) cost about one pass over the document instead of three. The
    text of a container is composed from its items' texts, which is what ``json.dumps`` with
    sorted keys and no spaces writes; a list or object of plain items (floats, strings, booleans,
    null; or lists of those) is written by the C encoder in one call. Anything else (integers,
    other types, keys that are not strings) goes through the definition,
    :func:`_reference_canonical`, item by item; a non-finite number raises its ValueError
    at the same item as the definition does.
    """

    def __init__(self):
        self._memo: dict[int, tuple[object, str]] = {}  # id -> (the value, kept alive; its text)

    def text(self, value) -> str:
        kind = type(value)
        if kind is float:
            return _number(value)
        if kind is str:
            return _encode_str(value)
        if kind is bool or value is None:
            return _SCALARS[value]
        if kind is int:
            return _number(value)
        if kind is list or kind is dict or kind is tuple:
            seen = self._memo.get(id(value))
            if seen is not None:
                return seen[1]
            text = self._list(value) if kind is not dict else self._dict(value)
            self._memo[id(value)] = (value, text)
            return text
        return _reference_canonical(value)

    def _list(self, items) -> str:
        if _plain_items(items):
            try:
                return _DUMPS(items)
            except ValueError:  # a non-finite number: the item by item path names it
                pass
        return "[" + ",".join([self.text(v) for v in items]) + "]"

    def _dict(self, obj: dict) -> str:
        if not all(type(k) is str for k in obj):
            return _reference_canonical(obj)  # keys made strings (and merged) as the definition does
        if _PLAIN.issuperset(map(type, obj.values())):
            try:
                return _DUMPS(obj)
            except ValueError:
                pass
        texts = {k: self.text(v) for k, v in obj.items()}  # in the document's order: the first error is its
        return "{" + ",".join([f"{_encode_str(k)}:{texts[k]}" for k in sorted(texts)]) + "}"


def _plain_items(items) -> bool:
    """True for a list of plain values, or of lists of plain values (a grid)."""
    kinds = set(map(type, items))
    if kinds <= _PLAIN:
        return True
    return kinds == {list} and all(_PLAIN.issuperset(map(type, row)) for row in items)


def _number(value) -> str:
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"the number {value} is not finite")
    return repr(number)


def _encode_str(text: str) -> str:
    return json.encoder.encode_basestring_ascii(text)


_PART_KEYS = {"press": ("press",), "thickness": ("thickness_mm",), "transforms and punch axes":
              ("tf_press_design", "tf_press_flat", "punch_x_mm", "punch_y_mm"), "inputs": ("inputs",),
              "validation": ("validation",), "format": ("format", "version")}


def document_parts(doc: dict) -> dict:
    """``{part name: JSON value}``: the job document split into the parts a seal names.

    Parts: ``press``, ``thickness``, ``transforms and punch axes``, ``inputs``, ``validation``,
    ``format``, ``plate layout``, ``material``, ``step K`` (each step), ``number of steps``,
    ``section N placement`` (plate centre, marks, transforms, layout), ``section N step K``,
    ``section N other`` (weights, reports), ``number of sections`` and ``planner's reports``
    (every other key).
    """
    parts, used = {}, {SEAL_KEY, "steps", "plate", "sections"}
    for name, keys in _PART_KEYS.items():
        parts[name] = [doc.get(k) for k in keys]
        used |= set(keys)
    plate = doc.get("plate") if isinstance(doc.get("plate"), dict) else {"(not an object)": doc.get("plate")}
    parts["plate layout"] = {k: v for k, v in plate.items() if k != "material"}
    parts["material"] = plate.get("material")
    _steps_parts(parts, "", doc.get("steps"))
    sections = doc.get("sections")
    if isinstance(sections, list):
        parts["number of sections"] = len(sections)
        for n, sec in enumerate(sections, start=1):
            sec = sec if isinstance(sec, dict) else {"(not an object)": sec}
            placement = ("index", "cell", "plate_centre_mm", "marks", "tf_press_design", "tf_press_flat", "plate")
            parts[f"section {n} placement"] = [sec.get(k) for k in placement]
            _steps_parts(parts, f"section {n} ", sec.get("steps"))
            parts[f"section {n} other"] = {k: v for k, v in sec.items() if k not in placement and k != "steps"}
    elif sections is not None:
        parts["number of sections"] = sections
    parts["planner's reports"] = {k: v for k, v in doc.items() if k not in used}
    return parts


def _steps_parts(parts: dict, where: str, steps) -> None:
    if not isinstance(steps, list):
        parts[f"{where}steps"] = steps
        return
    parts[f"{where}number of steps"] = len(steps)
    for k, step in enumerate(steps, start=1):
        parts[f"{where}step {k}"] = step


def _mac(key: bytes, name: str, value, canon: _Canonical | None = None) -> str:
    """HMAC of a part's name and canonical form; ``canon`` shared by the calls of one seal or check."""
    text = (canon or _Canonical()).text(value)
    return hmac.new(key, name.encode() + b"\0" + text.encode(), hashlib.sha256).hexdigest()


# ---------------------------------------------------------------- seal/verify ---
def seal_document(doc: dict, key: bytes, *, sealed_by: str, reason: str | None = None) -> dict:
    """The document with a fresh ``"seal"`` block (any old one replaced); ``doc`` is not changed.

    Parameters
    ----------
    doc : dict
        A job document (JSON values, finite numbers).
    key : bytes
        The installation's key (:func:`load_key`).
    sealed_by : str
        What sealed it (``"mppf plan"``, ``"mppf loop"``, ``"mppf reseal by NAME"``).
    reason : str, optional
        Why it was resealed (``mppf reseal --reason``).

    The seal holds no time, so the same plan gives the same file, byte for byte (the audit log
    records when a job was resealed).
    """
    body = {k: v for k, v in doc.items() if k != SEAL_KEY}
    canon = _Canonical()
    seal = {"algorithm": ALGORITHM, "key_id": key_id(key), "sealed_by": sealed_by,
            "parts": {name: _mac(key, name, value, canon) for name, value in document_parts(body).items()}}
    if reason:
        seal["reason"] = reason
    seal["content_mac"] = _mac(key, "content", body, canon)
    seal["mac"] = _mac(key, "job", {**body, SEAL_KEY: seal}, canon)
    return {**body, SEAL_KEY: seal}


def changed_parts(doc: dict, key: bytes) -> list[str]:
    """The parts of ``doc`` whose HMAC differs from its seal's (added and removed parts named so)."""
    stored = doc[SEAL_KEY].get("parts") if isinstance(doc.get(SEAL_KEY), dict) else None
    stored = stored if isinstance(stored, dict) else {}
    canon = _Canonical()
    now = {name: _mac(key, name, value, canon) for name, value in document_parts(
        {k: v for k, v in doc.items() if k != SEAL_KEY}).items()}
    changed = [name for name in now if name in stored and not hmac.compare_digest(str(stored[name]), now[name])]
    return changed + _whole_sections([n for n in now if n not in stored], "added") + \
        _whole_sections([n for n in stored if n not in now], "removed")


def _whole_sections(names: list, how: str) -> list[str]:
    """``names`` tagged ``(how)``; every part of a section added or removed as a whole named once (``section 6``)."""
    whole = {name[: -len(" placement")] for name in names if name.startswith("section ") and
             name.endswith(" placement")}
    out = []
    for name in names:
        section = " ".join(name.split()[:2]) if name.startswith("section ") else None
        shown = f"{section if section in whole else name} ({how})"
        if shown not in out:
            out.append(shown)
    return out


def verify_document(doc: dict, source: str, key: bytes | None = None) -> dict:
    """Check the seal of a job document; its seal block when it matches.

    Raises
    ------
    SealError
        No seal, a seal of another installation's key, or content that differs from the seal
        (naming the parts that changed: strokes of step K, section N placement, press, ...).
    ConfigError
        The key cannot be read, or the document holds values that are not plain JSON.
    """
    seal = doc.get(SEAL_KEY)
    if not isinstance(seal, dict) or not isinstance(seal.get("mac"), str):
        raise SealError(f"{source}: the job has no seal (it was not written by 'mppf plan', or its seal was "
                          "removed)", hint="re-plan the plate with 'mppf plan'; for a deliberate change run "
                                           f"'mppf reseal {source} --reason \"...\"'")
    key = load_key() if key is None else key
    if seal.get("key_id") != key_id(key):
        raise SealError(f"{source}: the job was sealed by another installation (seal key {seal.get('key_id')!r}, "
                          f"this installation's is {key_id(key)!r})",
                          hint="plan the plate on this installation, or check the job and run "
                               f"'mppf reseal {source} --reason \"...\"'")
    try:
        expected = _mac(key, "job", {**{k: v for k, v in doc.items() if k != SEAL_KEY},
                                     SEAL_KEY: {k: v for k, v in seal.items() if k != "mac"}})
        matches = hmac.compare_digest(expected, seal["mac"])
        changed = []
        if not matches:  # what changed: nothing of the content (the seal block was edited), or these parts
            body = {k: v for k, v in doc.items() if k != SEAL_KEY}
            if not hmac.compare_digest(_mac(key, "content", body), str(seal.get("content_mac"))):
                changed = changed_parts(doc, key)
    except ValueError as exc:
        raise ConfigError(f"{source}: the job holds a value that is not plain JSON ({exc})",
                          hint="re-plan the plate with 'mppf plan'") from None
    if not matches:
        what = ", ".join(changed[:12]) + (f" and {len(changed) - 12} more" if len(changed) > 12 else "") \
            if changed else "the seal block itself"
        raise SealError(f"{source}: the job was changed after it was sealed (by {seal.get('sealed_by', '?')}): "
                          f"changed: {what}; nothing was sent to the press",
                          hint="re-plan the plate with 'mppf plan' (never edit a job by hand); for a deliberate "
                               f"change run 'mppf reseal {source} --reason \"...\"'")
    return seal
