"""mppf: shop-floor software of a multi-point press for ship-hull plates.

The geometry and planning modules (``mppf.io``, ``mppf.frame``, ``mppf.surface``,
``mppf.register``, ``mppf.localize``, ``mppf.unfold``, ``mppf.plan``, ...) are pure:
arrays in, arrays out, lengths in millimetres. They import neither ``mppf.drivers``
nor ``mppf.sim``.
"""

from mppf.errors import MppfError

__version__ = "0.1.0"
__all__ = ["MppfError", "__version__"]
