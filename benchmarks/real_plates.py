"""Real hull plates for the batch benchmark: cut from the KCS hull IGES and the bundled hull data.

The KCS hull (``/work/shared/data/cad/ship_kcs.igs``, model scale 1:31.6) is sampled once in blocks
of 12 m along x and 0-18 m of girth from the keel, at 100 mm, by :func:`mppf.geometry.stations.sample_girth`
(the sampler of ``mppf extract --girth``): about 1 s of CPU per block. Each plate is a window of a
block between two butts (x) and two seams (girths): 6-12 m long and 1.8-3.4 m wide, so a window is
exactly the grid ``mppf extract hull.igs --scale 31.6 --x X0 X1 --girth G0 G1 --spacing 100`` gives.
The bundled real plates (the six 3 x 2 m hull patches of ``hull/`` and the 9 m KCS stern plate) are
added as they are. The designs and the manifest are written once into a cache folder (ignored by git).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from mppf.geometry.write import write_points

SHARED = Path("/work/shared/data")
KCS_IGES = SHARED / "cad" / "ship_kcs.igs"
KCS_SCALE = 31.6
SPACING_MM = 100.0
BLOCK_LENGTH_MM = 12000.0
BLOCK_GIRTH_MM = 18000.0
BLOCK_X0_MM = np.arange(17000.0, 190000.0, BLOCK_LENGTH_MM)
"""Block starts: from where the KCS has a keel (x about 17 m) to the bow flare (the last ends at 197 m)."""
BUNDLED = ["hull/P1_midbody_bilge.csv", "hull/P2_bow_flare.csv", "hull/P3_stern_saddle.csv",
           "hull/kcs/K1_midbody_bilge.csv", "hull/kcs/K2_fwd_bilge_convex.csv", "hull/kcs/K3_stern_saddle.csv"]
LONG_KCS = Path(__file__).resolve().parents[1] / "mppf" / "examples" / "long" / "kcs_stern_bilge_9000x2400.csv"


def hull_blocks(cache: Path) -> list[np.ndarray]:
    """The KCS hull's blocks, (121, 181, 3) mm each (x stations by girths), sampled once and cached."""
    from mppf.geometry.cad import CadModel
    from mppf.geometry.stations import sample_girth

    path = cache / "kcs_blocks.npz"
    if path.exists():
        with np.load(path) as data:
            return [data[f"b{k}"] for k in range(len(BLOCK_X0_MM))]
    x_rows = int(BLOCK_LENGTH_MM / SPACING_MM) + 1
    girth = np.arange(0.0, BLOCK_GIRTH_MM + 1.0, SPACING_MM)
    with CadModel(KCS_IGES, scale=KCS_SCALE) as model:
        blocks = [sample_girth(model, x0 + SPACING_MM * np.arange(x_rows), girth) for x0 in BLOCK_X0_MM]
    np.savez_compressed(path, **{f"b{k}": b for k, b in enumerate(blocks)})
    return blocks


def write_real_batch(cache: Path, n: int, seed: int = 42) -> tuple[Path, dict]:
    """Design files and a manifest of ``n`` real plates in ``cache``; the plates' origins by name.

    The first plates are the bundled ones (hull patches, the 9 m KCS stern plate), the rest windows
    of the KCS blocks at seeded random butts and seams. Files already written are kept.
    """
    cache.mkdir(parents=True, exist_ok=True)
    (cache / ".gitignore").write_text("*\n")
    rng = np.random.default_rng(seed)
    lines, kinds = ["name,design,thickness_mm,material"], {}
    sources = [SHARED / p for p in BUNDLED] + [LONG_KCS]
    for k in range(min(n, len(sources))):
        name = f"real{k:04d}"
        target = cache / f"{name}.csv"
        if not target.exists():
            shutil.copyfile(sources[k], target)
        lines.append(f"{name},{name}.csv,{rng.choice([12, 16, 20, 25])},steel")
        kinds[name] = "bundled " + sources[k].stem.split("_")[0]
    blocks = hull_blocks(cache) if n > len(sources) else []
    for k in range(len(sources), n):
        name = f"real{k:04d}"
        block = rng.integers(len(blocks))
        rows = int(rng.uniform(6000.0, 12000.0) / SPACING_MM) + 1
        cols = int(rng.uniform(1800.0, 3400.0) / SPACING_MM) + 1
        r0 = rng.integers(0, blocks[block].shape[0] - rows + 1)
        c0 = rng.integers(0, blocks[block].shape[1] - cols + 1)
        target = cache / f"{name}.csv"
        if not target.exists():
            x0 = BLOCK_X0_MM[block] + r0 * SPACING_MM
            window = blocks[block][r0:r0 + rows, c0:c0 + cols].reshape(-1, 3)
            write_points(target, window, header=(f"plate cut from ship_kcs.igs: x {x0:.0f}-"
                                                 f"{x0 + (rows - 1) * SPACING_MM:.0f} mm, girth "
                                                 f"{c0 * SPACING_MM:.0f}-{(c0 + cols - 1) * SPACING_MM:.0f} mm, "
                                                 f"grid {rows} x {cols}"))
        lines.append(f"{name},{name}.csv,{rng.choice([12, 16, 20, 25])},steel")
        kinds[name] = "KCS " + ("9-12 m" if rows > 90 else "6-9 m")
    manifest = cache / "plates.csv"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest, kinds
