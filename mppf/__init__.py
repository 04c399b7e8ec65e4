"""mppf: shop-floor software of a multi-point press for ship-hull plates.

The geometry and planning modules (``mppf.geometry.io``, ``mppf.geometry.frame``, ``mppf.geometry.surface``,
``mppf.registration.register``, ``mppf.geometry.localize``, ``mppf.geometry.unfold``, ``mppf.planning.plan``, ...) are pure:
arrays in, arrays out, lengths in millimetres. They import neither ``mppf.drivers``
nor ``mppf.sim``.
"""

from mppf.core.errors import MppfError

__version__ = "0.1.0"
__all__ = ["MppfError", "__version__"]
