"""``python -m mppf`` runs the command line."""

from mppf.cli import main

main()
