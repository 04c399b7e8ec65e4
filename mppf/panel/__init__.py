"""The operator's panel: a local web page beside the press (``mppf panel``, see ``docs/panel.md``).

Views: where to lay the plate, the live press, the loop, the history, and STOP (a software
stop, the only command it sends). Modules: :mod:`~mppf.panel.app` (the ASGI app),
:mod:`~mppf.panel.config` (settings and the bind rule), :mod:`~mppf.panel.security` (token,
Host and Origin checks), :mod:`~mppf.panel.sources` (history, audit log, jobs),
:mod:`~mppf.panel.plc` (the live PLC reader and STOP), :mod:`~mppf.panel.live` (marks and
progress), :mod:`~mppf.panel.views` (what each view shows), and the drawings, reusable
by reports: :mod:`~mppf.panel.svg` (heat maps), :mod:`~mppf.panel.placement` (the bed and
the plate), :mod:`~mppf.panel.charts` (convergence).
"""
