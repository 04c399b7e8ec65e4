"""Reports: HTML pages and pictures (strain, strokes, deviation maps, convergence)."""
