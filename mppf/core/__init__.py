"""Shared foundations: errors, units-safe transforms, rigid fits, polygons, grids, validators, the press interface."""
