"""The one interface of the simulated plates the dry-run shop presses.

:class:`mppf.sim.shop.SimulatedPlateScanner` presses and scans a plate through these calls only.
Two plates implement it: the finite-difference steel plate (:class:`mppf.sim.plate.plate.SteelPlate`,
``plate_model="steel"``, ``--physics fd``) and the FE plate computed by CalculiX
(:class:`mppf.sim.fe.plate.FEPlate`, ``plate_model="fe"``, ``--physics fe``). What a press step
leaves (:attr:`SimulatedPlate.formed`) is what :class:`mppf.sim.scanner.SimulatedScanner` samples:
its outline, thickness, heights, normals and skin points (the interface of
:class:`mppf.sim.forming.FormedPlate`).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class SimulatedPlate(Protocol):
    """A simulated plate pressed step by step, its state saved and restored.

    The FE plate also takes ``progress`` (a callable given each line of ccx's progress); the shop sets
    it where the plate has it. It is not part of this interface: the steel plate computes in-process.
    """

    def place(self, placement_mm) -> None:
        """Shift the plate on the bed: the press's punch axes at press x, y + ``placement_mm`` (2,) mm in the
        plate's frame (the next section of a plate larger than the bed; (0, 0): the first placement). A plate
        that cannot be pressed in sections refuses any other placement (InputError)."""

    def press_step(self, upper_mm, lower_mm, active, *, share: float = 1.0) -> Any:
        """Press one step: tips (rows, cols) mm as read back (inactive entries ignored), ``active`` (rows, cols)
        bool; ``share`` in (0, 1] of the way from the last tips (a step stopped in its motion). Returns
        :attr:`formed`."""

    @property
    def formed(self) -> Any:
        """The plate after its last step, sprung back (what the scanner samples)."""

    def state_dict(self) -> dict:
        """Everything to rebuild the plate as it is now (``np.savez``-able)."""

    @classmethod
    def from_state(cls, state) -> SimulatedPlate:
        """The plate of :meth:`state_dict` (a dict, or the mapping ``np.load`` returns)."""
