"""``python -m mppf`` runs the command line."""

from mppf.cli import main

if __name__ == "__main__":  # not when a worker process (mppf.report.parallel) imports it
    main()
