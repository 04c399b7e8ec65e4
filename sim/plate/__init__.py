"""A simulated steel plate for dry runs and benchmarks, independent of the planner's plate model.

Modules (import what you need; this package imports nothing heavy):

- :mod:`~mppf.sim.plate.material`: the steel (E, nu, Hill 48 yield, Swift + linear hardening);
- :mod:`~mppf.sim.plate.scatter`: one seeded physical plate (plate-to-plate and spatial scatter);
- :mod:`~mppf.sim.plate.through_thickness`: layered return mapping, moments and consistent tangent;
- :mod:`~mppf.sim.plate.grid`: the bicubic B-spline Kirchhoff plate grid over the outline;
- :mod:`~mppf.sim.plate.contact`: unilateral ball-tip contacts and press compliance;
- :mod:`~mppf.sim.plate.predict`: the elastic contact problem on the punch axes (start of each increment);
- :mod:`~mppf.sim.plate.solve`: loaded (active set) and unloaded (springback) equilibrium;
- :mod:`~mppf.sim.plate.formed`: the formed plate as the scanner sees it;
- :mod:`~mppf.sim.plate.plate`: :class:`~mppf.sim.plate.plate.SteelPlate`, the plate pressed step by step.

See docs/simulator-plate.md.
"""
