"""Pictures (matplotlib, Agg backend): stroke maps, strain and deviation maps.

Plotting lives at the edge of the library: geometry and planning never import it.
"""

import matplotlib

matplotlib.use("Agg")
