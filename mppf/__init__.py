"""mppf: shop-floor software of a multi-point press for ship-hull plates.

One sub-package per stage of the procedure, in layers that import only downwards (see
``docs/architecture.md``, "Layers"): ``core``, ``model`` (the data every stage shares),
``geometry``, ``registration``, ``forming``, ``correct``, ``planning``, the PLC drivers
``mppf.drivers``, ``measure``, the simulators ``mppf.sim``, ``loop``, ``report``, ``panel``, ``cli``. Geometry,
planning and measurement are pure (arrays in, arrays out, lengths in millimetres) and import
neither ``mppf.drivers`` nor ``mppf.sim``.
"""

from mppf.core.errors import MppfError

__version__ = "0.2.0"
__all__ = ["MppfError", "__version__"]
