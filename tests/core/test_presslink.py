"""The press protocol (mppf.core.presslink) declares what the loop uses, and every press link has it."""

from __future__ import annotations

from driver_helpers import small_press

from mppf.core.presslink import PressLink
from mppf.sim.plc.link import InProcessPress


def test_the_press_links_name_the_job_they_press():
    with InProcessPress(small_press()) as link:
        assert isinstance(link, PressLink)
        assert link.job_sha256 is None
        link.job_sha256 = "a" * 64  # as the loop does before it presses a cycle
        assert link.job_sha256 == "a" * 64
    assert not isinstance(object(), PressLink)
