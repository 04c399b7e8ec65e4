"""Fast tests of the FE plate's mesh, deck writer and result readers (no ccx run)."""

from __future__ import annotations

import numpy as np
import pytest
from mppf.sim.fe import ccx
from mppf.sim.fe.deck import (
    LATER_LOAD_INCREMENT,
    MAX_CUTBACKS,
    RELEASE_INCREMENT,
    RETRACT_MM,
    flow_curve,
    history_deck,
    hold_nodes,
    model_lines,
    step_count,
)
from mppf.sim.fe.mesh import build_mesh
from mppf.sim.fe.results import last_of_steps, read_dat_forces, read_frd
from mppf.sim.plate.material import PlateSteel

from mppf.core.errors import FileFormatError, GeometryError, InputError
from mppf.model.press import example_press_path, load_press

OUTLINE = np.array([[-500.0, -320.0], [500.0, -320.0], [500.0, 320.0], [-500.0, 320.0]])


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def thickness(xy):
    """20 mm, 2 % thicker towards +x."""
    return 20.0 * (1.0 + 0.02 * np.asarray(xy)[:, 0] / 500.0)


def test_mesh_puts_node_columns_on_the_punch_axes_and_follows_the_local_thickness(press):
    mesh = build_mesh(press, OUTLINE, thickness, cells_per_pitch=2, layers=3)
    # 75 mm cells, axes at x +-75, +-225, +-375 and y +-75, +-225 (and the edge lines)
    assert len(mesh.bottom) == 6 * 4  # x: -375..375 (6 axes), y: -225..225 (4 axes)
    assert np.allclose(mesh.xyz_mm[mesh.bottom - 1, :2], mesh.punch_xy_mm)
    assert np.allclose(mesh.xyz_mm[mesh.top - 1, :2], mesh.punch_xy_mm)
    assert np.allclose(mesh.xyz_mm[mesh.bottom - 1, 2], 0.0)
    assert np.allclose(mesh.xyz_mm[mesh.top - 1, 2], thickness(mesh.punch_xy_mm))
    assert mesh.x_mm[0] == -500.0 and mesh.x_mm[-1] == 500.0
    assert np.all(np.diff(mesh.x_mm) > 0.25 * 75.0 - 1e-9)
    assert mesh.hexes.shape == ((len(mesh.x_mm) - 1) * (len(mesh.y_mm) - 1) * 3, 8)
    # every hexahedron has a positive volume (bottom face counter-clockwise seen from above)
    p = mesh.xyz_mm[mesh.hexes - 1]
    e1, e2, e3 = p[:, 1] - p[:, 0], p[:, 3] - p[:, 0], p[:, 4] - p[:, 0]
    assert np.all(np.einsum("ij,ij->i", np.cross(e1, e2), e3) > 0)


def test_mesh_of_a_plate_off_the_punches_is_refused(press):
    tiny = np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 60.0], [0.0, 60.0]]) + 10.0
    with pytest.raises(GeometryError, match="at least 3"):
        build_mesh(press, tiny, thickness, cells_per_pitch=2, layers=2)


def test_model_has_hexahedra_gaps_and_kinematic_hardening_per_yield_bin(press):
    mesh = build_mesh(press, OUTLINE, thickness, cells_per_pitch=1, layers=2)
    factor = np.where(mesh.hex_centre_xy_mm[:, 0] > 0, 1.02, 1.0)
    lines = model_lines(mesh, PlateSteel(), factor, 1e5)
    text = "\n".join(lines)
    m = len(mesh.bottom)
    gap_start = lines.index("*ELEMENT, TYPE=GAPUNI, ELSET=GAPS")
    assert sum(1 for line in lines[gap_start + 1:gap_start + 1 + 2 * m] if line.count(",") == 2) == 2 * m
    assert text.count("*MATERIAL") == 2 and text.count("HARDENING=KINEMATIC") == 2
    assert "0.,0.,0.,1.,,100000" in text
    curve = flow_curve(PlateSteel(), 1.02)
    assert curve[0, 1] == 0.0 and curve[0, 0] == pytest.approx(1.02 * 235.0)
    assert np.all(np.diff(curve[:, 0]) > 0)


def test_history_deck_replays_every_press_step_and_holds_each_release_by_fresh_nodes(press):
    mesh = build_mesh(press, OUTLINE, thickness, cells_per_pitch=1, layers=2)
    m = len(mesh.bottom)
    holds = [hold_nodes(mesh, k) for k in range(6)]
    assert len({int(n) for h in holds for n in h}) == 18  # no node held in two releases
    mid = mesh.column[..., 1]
    assert all(np.isin(h, mid[mid > 0]).all() for h in holds)  # mid-thickness nodes
    a, b, c = (mesh.xyz_mm[n - 1, :2] for n in holds[0])
    ab, ac = b - a, c - a
    assert abs(ab[0] * ac[1] - ab[1] * ac[0]) > 1e5  # a real triangle, not a line
    tips = np.concatenate([np.zeros(m), mesh.thickness_mm])
    first = history_deck(mesh, ["*NODE"], [(tips, None)])
    assert first.count("*STEP") == 2 == step_count(1) and first.count("*NODE FILE") == 2
    later = history_deck(mesh, ["*NODE"], [(tips, None), (tips - 10.0, tips + 5.0)])
    assert later.count("*STEP") == 5 == step_count(2) and later.count("*NODE FILE") == 2
    lower = mesh.node_count + 1 + np.arange(m)  # the lower tips' nodes (flat at z = 0)
    approach = later[later.index("** APPROACH"):later.index("** LOAD", later.index("** APPROACH"))]
    release = later[later.rindex("** RELEASE"):]
    assert all(f"{lower[i]},3,3,{-10.0 - RETRACT_MM:.6f}" in release for i in range(m))  # every tip retracts
    assert all(f"{lower[i]},3,3,5.000000" in approach for i in range(m))  # and touches again
    frozen = release[release.index("*BOUNDARY, FIXED"):].split("\n")[1:4]
    assert frozen == [f"{int(n)},3,3" for n in holds[1]]
    assert approach[approach.index("*BOUNDARY, FIXED"):].split("\n")[1:4] == [f"{int(n)},3,3" for n in holds[0]]


def test_the_release_starts_with_the_whole_step_and_a_later_load_with_a_small_increment(press):
    mesh = build_mesh(press, OUTLINE, thickness, cells_per_pitch=1, layers=2)
    m = len(mesh.bottom)
    tips = np.concatenate([np.zeros(m), mesh.thickness_mm])
    deck = history_deck(mesh, ["*NODE"], [(tips, None), (tips - 10.0, tips + 5.0)])
    first = [line for line in deck.split("\n") if line.endswith((",1.,1e-6,0.5", ",1.,1e-6,1"))]
    # LOAD1, RELEASE1, APPROACH, LOAD2, RELEASE2: first increment, step 1, smallest 1e-6, largest
    assert first == ["0.25,1.,1e-6,0.5", f"{RELEASE_INCREMENT:g},1.,1e-6,1", "1,1.,1e-6,0.5",
                     f"{LATER_LOAD_INCREMENT:g},1.,1e-6,0.5", f"{RELEASE_INCREMENT:g},1.,1e-6,1"]
    assert RELEASE_INCREMENT == 1.0 and LATER_LOAD_INCREMENT < 0.25


def test_every_step_may_cut_an_increment_back_until_the_tips_retract_microns(press):
    # the release's gaps must open one by one: ccx's default of 5 cutbacks left a first increment that retracted
    # the tips 0.29 mm, and every gap of a plate pressed with a large stroke change opened in it at once
    mesh = build_mesh(press, OUTLINE, thickness, cells_per_pitch=1, layers=2)
    m = len(mesh.bottom)
    tips = np.concatenate([np.zeros(m), mesh.thickness_mm])
    deck = history_deck(mesh, ["*NODE"], [(tips, None), (tips - 10.0, tips + 5.0)]).split("\n")
    controls = [deck[i + 1] for i, line in enumerate(deck) if line == "*CONTROLS, PARAMETERS=TIME INCREMENTATION"]
    assert controls == [f"8,10,9,200,10,4,0,{MAX_CUTBACKS}"] * step_count(2)
    smallest = RELEASE_INCREMENT / 4.0 ** MAX_CUTBACKS  # ccx cuts back by 4 on divergence
    assert RETRACT_MM * smallest < 0.002  # mm: 200 N of gap force at 1e5 N/mm
    assert smallest > 1e-6 / 4.0  # the step's smallest increment is not reached before


def test_status_summary_counts_increments_cutbacks_and_iterations(tmp_path):
    sta = tmp_path / "plate.sta"
    sta.write_text("SUMMARY OF JOB INFORMATION\n  STEP      INC     ATT  ITRS     TOT TIME     STEP TIME      INC TIME\n"
                   "     1          1     1     8  0.25  0.25  0.25\n     1          2     1     5  0.5  0.5  0.25\n"
                   "     2          1     1U   10  1.0  0.0  0.05\n     2          1     2U    6  1.0  0.0  0.0125\n"
                   "     2          1     3     4  1.0  0.0125  0.0125\n")
    assert ccx.sta_summary(sta) == {1: (2, 0, 13), 2: (1, 2, 20)}
    assert ccx.sta_summary(tmp_path / "missing.sta") == {}


FRD = """    1C
    1UUSER
    1PSTEP                         1           1           1
  100CL  101 1.000000000           2                     0    1           1
 -4  DISP        4    1
 -5  D1          1    2    1    0
 -5  D2          1    2    2    0
 -5  D3          1    2    3    0
 -5  ALL         1    2    0    0    1ALL
 -1         1 1.00000E+00 0.00000E+00-2.50000E+00
 -1         2-1.00000E+00 2.00000E-01 3.00000E+00
 -3
    1PSTEP                         2           1           2
  100CL  101 2.000000000           2                     0    2           1
 -4  DISP        4    1
 -5  D1          1    2    1    0
 -1         1 5.00000E-01 0.00000E+00-1.25000E+00
 -1         2-5.00000E-01 1.00000E-01 1.50000E+00
 -3
 9999
"""


def test_frd_reader_returns_each_steps_last_displacements():
    blocks = read_frd(FRD)
    assert [b.step for b in blocks] == [1, 2]
    steps = last_of_steps(blocks)
    assert steps[2].time == 2.0
    assert np.allclose(steps[1].values, [[1.0, 0.0, -2.5], [-1.0, 0.2, 3.0]])
    assert steps[2].nodes.tolist() == [1, 2]
    with pytest.raises(FileFormatError, match="bad result line"):
        read_frd(FRD.replace("-1.25000E+00", "-1.2x000E+00"))


def test_dat_reader_returns_forces_of_a_node_set():
    dat = ("\n forces (fx,fy,fz) for set TIPS and time  0.1000000E+01\n\n"
           "        11  1.000000E+00 -2.000000E+00  3.500000E+03\n        12  0.0 0.0 -3.5E+03\n\n")
    (time, nodes, forces), = read_dat_forces(dat, "tips")
    assert time == 1.0 and nodes.tolist() == [11, 12]
    assert forces[:, 2].tolist() == [3500.0, -3500.0]


def test_missing_ccx_says_how_to_install_it(monkeypatch):
    monkeypatch.setenv("MPPF_CCX", "ccx-that-is-not-installed")
    with pytest.raises(InputError, match="apt-get install calculix-ccx") as info:
        ccx.run_ccx("*NODE\n")
    assert info.value.exit_code == 2
