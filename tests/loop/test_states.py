"""The names of the loop (mppf.loop.states): each state, decision and status is the text the history stores."""

from __future__ import annotations

from mppf.loop.states import DECISIONS, PLATE_STATUSES, STATES, CycleState, Decision, PlateStatus


def test_a_name_is_its_text_as_stored():
    assert CycleState.PLANNED == "planned" and CycleState("compared") is CycleState.COMPARED
    assert f"{Decision.CANNOT_CONVERGE}" == "cannot_converge" and str(PlateStatus.ACTIVE) == "active"


def test_the_cycle_states_in_the_order_a_cycle_moves_through_them():
    assert [str(s) for s in STATES] == ["planned", "pressing", "pressed", "scanned", "compared", "corrected", "done"]


def test_a_plate_ends_with_its_final_decision_as_its_status():
    """Every decision but CONTINUE ends the loop and is a plate status; ACTIVE is the one status that is none."""
    final = {str(d) for d in DECISIONS} - {"continue"}
    assert final == {str(s) for s in PLATE_STATUSES} - {"active"}
    assert all(PlateStatus(str(d)) == d for d in DECISIONS if d is not Decision.CONTINUE)
