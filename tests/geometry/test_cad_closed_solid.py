"""A closed CAD solid (a box, a sphere) is not a plate: refused naming the file, not read as a flipped surface."""

from __future__ import annotations

import pytest

from mppf.cli import main

pytest.importorskip("gmsh")


@pytest.mark.parametrize("name, faces", [("box.step", 6), ("sphere.step", 1)])
def test_a_closed_solid_is_refused(tmp_path, capsys, name, faces):
    from mppf.geometry.files import quiet
    from mppf.geometry.gmsh_gate import GmshModel

    path = tmp_path / name
    with GmshModel() as model, model.use() as gmsh, quiet():
        occ = gmsh.model.occ
        occ.addBox(0, 0, 0, 1000, 800, 20) if name.startswith("box") else occ.addSphere(0, 0, 0, 500)
        occ.synchronize()
        gmsh.write(str(path))
    assert main(["fit", str(path)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{name}: is a closed solid ({faces} face(s) without a free edge" in err and "Traceback" not in err
