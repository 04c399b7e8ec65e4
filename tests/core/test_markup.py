"""Markup escaping (mppf.core.markup): user text printed through rich unchanged."""

from __future__ import annotations

import pytest
from rich.console import Console
from rich.markup import escape

from mppf.core.markup import escape_markup


@pytest.mark.parametrize("text", ["B12[/]P3", "P3[rev2].csv", "MPP [/] press", "[bold]x[/bold]", "a\\[b]",
                                  "plain", "[/", "[@click]"])
def test_escape_markup_matches_rich_and_prints_the_text_unchanged(text):
    assert escape_markup(text) == escape(text)
    console = Console(width=200, record=True, color_system=None)
    console.print(escape_markup(text))
    assert console.export_text().rstrip("\n") == text
