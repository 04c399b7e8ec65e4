"""The FE plate: a steel plate on the press computed by CalculiX (``ccx``), for dry runs and try-outs.

Modules (import what you need; this package imports nothing heavy):

- :mod:`~mppf.sim.fe.mesh`: C3D8I layers over the outline, node columns on the punch axes;
- :mod:`~mppf.sim.fe.deck`: the input deck (model, approach / load / release steps);
- :mod:`~mppf.sim.fe.ccx`: running ccx in a temporary folder (progress, log kept on failure);
- :mod:`~mppf.sim.fe.results`: reading the .frd and .dat files;
- :mod:`~mppf.sim.fe.formed`: the formed plate as the scanner sees it;
- :mod:`~mppf.sim.fe.plate`: :class:`~mppf.sim.fe.plate.FEPlate`, pressed step by step.

See docs/simulator-fe.md.
"""
