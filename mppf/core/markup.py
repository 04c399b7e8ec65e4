"""User text inside rich markup: plate ids, press names and file names printed as they are.

rich reads ``[...]`` in printed text as markup: a plate id ``B12[/]P3`` would end a style
(and raise), a file ``P3[rev2].csv`` would lose its bracket. :func:`escape_markup` does what
``rich.markup.escape`` does, without importing rich (start-up time of the command line).
"""

from __future__ import annotations

import re

_MARKUP = re.compile(r"(\\*)(\[[a-z#/@][^[]*?])")


def escape_markup(text) -> str:
    """``str(text)`` with every markup tag escaped, so rich prints it unchanged (as ``rich.markup.escape``)."""

    def double_backslashes(match: re.Match) -> str:
        backslashes, tag = match.groups()
        return f"{backslashes}{backslashes}\\{tag}"

    text = _MARKUP.sub(double_backslashes, str(text))
    if text.endswith("\\") and not text.endswith("\\\\"):
        return text + "\\"
    return text
