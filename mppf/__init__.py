"""mppf: shop-floor software of a multi-point press for ship-hull plates.

One sub-package per stage of the procedure (see ``docs/architecture.md``): ``core``,
``geometry``, ``registration``, ``planning``, ``forming``, ``measure``, ``correct``, ``loop``,
``report``, ``cli``; PLC drivers in ``mppf.drivers``, simulators in ``mppf.sim``. Geometry,
planning and measurement are pure (arrays in, arrays out, lengths in millimetres) and import
neither ``mppf.drivers`` nor ``mppf.sim``.
"""

from mppf.core.errors import MppfError

__version__ = "0.2.0"
__all__ = ["MppfError", "__version__"]
