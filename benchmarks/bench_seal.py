"""Benchmark: what the job seal and the plan's re-derived checks cost (issue 38).

A single-piece plate (3.0 x 2.0 m) and a plate in 6 sections (7.5 x 2.4 m), both cylinders of
20 m radius planned on the example press: the time to save a job (seal included), to load it
(its seal checked), the seal check alone (:func:`mppf.core.seal.verify_document`) and the plan's
re-derived checks (:func:`mppf.planning.job_checks.check_plan`), each the mean of ``--repeat``
runs. The key is a temporary one (``MPPF_SEAL_KEY``), not the installation's.

Run: ``python benchmarks/bench_seal.py [--repeat N]``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path


def _mean_s(fn, repeat: int) -> float:
    start = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - start) / repeat


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["MPPF_SEAL_KEY"] = str(Path(tmp) / "seal.key")
        from mppf.core.seal import verify_document
        from mppf.examples.analytic import cylinder_plate
        from mppf.model.job import read_job_document
        from mppf.model.press import example_press_path, load_press
        from mppf.planning.job import load_job, save_job
        from mppf.planning.job_checks import check_plan
        from mppf.planning.sectional import plan_plate

        press = load_press(example_press_path())
        print(f"{'plate':<26}{'file':>8}{'steps':>7}{'save':>10}{'load':>10}{'seal check':>12}{'check_plan':>12}")
        for name, (length_mm, width_mm) in {"single, 3.0 x 2.0 m": (3000.0, 2000.0),
                                            "6 sections, 7.5 x 2.4 m": (7500.0, 2400.0)}.items():
            design, flat = cylinder_plate(length_mm, width_mm, 20000.0)
            job = plan_plate(design, flat, press, 20.0)
            path = save_job(job, Path(tmp) / "job.json")
            doc = read_job_document(path)
            steps = sum(len(s.steps) for s in job.sections) if job.sections else len(job.steps)
            runs = (lambda job=job, path=path: save_job(job, path), lambda path=path: load_job(path),
                    lambda doc=doc: verify_document(doc, "job"), lambda job=job: check_plan(job))
            times = [_mean_s(f, args.repeat) * 1e3 for f in runs]
            print(f"{name:<26}{path.stat().st_size / 1e3:>6.0f}kB{steps:>7}"
                  + "".join(f"{t:>9.1f}ms" for t in times[:2]) + "".join(f"{t:>10.1f}ms" for t in times[2:]))


if __name__ == "__main__":
    main()
