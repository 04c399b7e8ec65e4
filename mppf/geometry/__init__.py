"""Geometry: reading plate files, the plate's own frame, fitted surfaces z = D(u, v), foot points, unfolding."""
