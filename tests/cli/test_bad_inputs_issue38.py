"""The bad-input corpus of issue 38 (data only; run by ``test_bad_inputs.py`` with the rest of the corpus).

Jobs edited by hand within the limits, a job's press block raised, section placements moved, a
section deleted, steps duplicated, the validation or thickness edited: each refused by its seal
(what changed named), and again when the edit is sealed by someone who has the key (the machine's
press, the plan's placements re-derived, the validator). Then the other findings: plate names
that are paths, extra manifest fields, PLY counts beyond the file, a mark 10 km away, ... Every
case must give exit 2 and a message with its words, and write nothing to any PLC.
"""

from __future__ import annotations

import json
from pathlib import Path

_PRESS = Path(__file__).resolve().parents[2] / "mppf" / "examples" / "press.toml"


def _edited(source: str, edit, reseal: bool = False):
    """A file maker: the good job ``source`` edited (and sealed again with the installation's key)."""
    def make(path: Path, good) -> None:
        doc = json.loads(Path(good[source]).read_text())
        edit(doc)
        if reseal:
            from mppf.core.seal import load_key, seal_document

            doc = seal_document(doc, load_key(), sealed_by="someone who has the key")
        path.write_text(json.dumps(doc, indent=1))
    return make


def _active(doc, step: int = -1, steps_of=None):
    """(upper row, lower row, col) of the first active punch of a step."""
    step_doc = (steps_of or doc)["steps"][step]
    for r, row in enumerate(step_doc["active"]):
        for c, on in enumerate(row):
            if on:
                return step_doc["upper_mm"][r], step_doc["lower_mm"][r], c
    raise AssertionError("no active punch")


def _pair_up(mm: float, section: int | None = None):
    def edit(doc):
        up, lo, c = _active(doc, steps_of=None if section is None else doc["sections"][section - 1])
        up[c] += mm
        lo[c] += mm
    return edit


def _upper_up(mm: float):
    def edit(doc):
        up, _, c = _active(doc)
        up[c] += mm
    return edit


def _dimpling_raised(doc):
    doc["press"]["forming"]["max_neighbour_diff_mm"] = 300.0
    _pair_up(100.0)(doc)


def _section(index: int, edit):
    def apply(doc):
        edit(doc["sections"][index - 1])
    return apply


def _shift(key_path, dx: float):
    def edit(sec):
        target = sec
        for key in key_path[:-1]:
            target = target[key]
        value = target[key_path[-1]]
        if isinstance(value[0], list):
            for row in value:
                row[0] += dx
        else:
            value[0] += dx
    return edit


def _flat_tf_shift(sec):
    sec["tf_press_flat"][0][3] += 500.0


def _mark_punch(sec):
    sec["marks"]["punches"][0][1] += 1


def _drop_last_section(doc):
    doc["sections"].pop()


def _duplicate_step(doc):
    doc["steps"].insert(0, json.loads(json.dumps(doc["steps"][0])))


def _validation_failed(doc):
    doc["validation"]["passed"] = False


def _thickness(doc):
    doc["thickness_mm"] = 19.0


def _unsealed_v2(doc):
    doc.pop("seal")
    doc["version"] = 2


def _press_key(table: str, key: str, value):
    def edit(doc):
        doc["press"][table][key] = value
    return edit


SEAL = "the job was changed after it was sealed"
EDITS = {  # key: (good job, edit, words with the seal, words when sealed again by someone with the key)
    "pair_up_2": ("job", _pair_up(2.0), [SEAL, "step"], None),
    "upper_up_1_5": ("job", _upper_up(1.5), [SEAL, "step"], None),
    "section4_pair_up_2": ("sectional_job", _pair_up(2.0, section=4), [SEAL, "section 4 step"], None),
    "dimpling_300": ("job", _dimpling_raised, [SEAL, "press"],
                     ["planned for another press", "max_neighbour_diff_mm is 300.0 in the job, 30.0 in"]),
    "pitch_140": ("job", _press_key("matrix", "pitch_x_mm", 140.0), [SEAL, "press"],
                  ["planned for another press", "pitch_x_mm is 140.0 in the job, 150.0 in"]),
    "lower_park_250": ("job", _press_key("lower", "park_mm", 250.0), [SEAL, "press"],
                       ["planned for another press", "park_mm is 250.0 in the job, -400.0 in"]),
    "section2_centre_1000": ("sectional_job", _section(2, _shift(("plate_centre_mm",), 1000.0)),
                             [SEAL, "section 2 placement"],
                             ["does not follow from its own plan", "section 2 plate centre"]),
    "section3_marks_300": ("sectional_job", _section(3, _shift(("marks", "press_mm"), 300.0)),
                           [SEAL, "section 3 placement"],
                           ["does not follow from its own plan", "section 3 marks on the bed"]),
    "section3_plate_marks_300": ("sectional_job", _section(3, _shift(("marks", "plate_mm"), 300.0)),
                                 [SEAL, "section 3 placement"], ["section 3 marks in plate coordinates"]),
    "section2_flat_tf_500": ("sectional_job", _section(2, _flat_tf_shift), [SEAL, "section 2 placement"],
                             ["does not follow from its own plan", "section 2 plate centre"]),
    "section2_mark_punch": ("sectional_job", _section(2, _mark_punch), [SEAL, "section 2 placement"],
                            ["section 2 mark"]),
    "last_section_deleted": ("sectional_job", _drop_last_section, [SEAL, "number of sections"],
                             ["the plan has 6 section(s), the job holds 5"]),
    "step_duplicated": ("job", _duplicate_step, [SEAL, "step"], ["step 2 repeats step 1"]),
    "validation_false": ("job", _validation_failed, [SEAL, "validation"], ["validation did not pass"]),
    "thickness_19": ("job", _thickness, [SEAL, "thickness"], None),
    "seal_removed": ("job", lambda d: d.pop("seal"), ["the job has no seal"], None),
    "unsealed_v2": ("job", _unsealed_v2, ["older, unsealed job (version 2)", "mppf reseal"], None),
}

FILES38 = {}
for _key, (_source, _edit, _, _again) in EDITS.items():
    FILES38[f"job38_{_key}"] = (f"{_key}.job.json", _edited(_source, _edit))
    if _again:
        FILES38[f"job38_{_key}_resealed"] = (f"{_key}.resealed.job.json", _edited(_source, _edit, reseal=True))

def _las_scale_zero(path: Path, good) -> None:
    import laspy
    import numpy as np

    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales, header.offsets = np.array([0.0, 0.001, 0.001]), np.zeros(3)
    las = laspy.LasData(header)
    grid = np.arange(2501)
    las.X, las.Y, las.Z = grid, grid % 50, grid // 50
    las.write(str(path))


def _metres(path: Path, good) -> None:
    text = Path(good["design"]).read_text().splitlines()
    rows = [",".join(f"{float(v) / 1000.0:.6f}" for v in line.split(",")) for line in text if line[:1] not in "#x"]
    path.write_text("\n".join(rows) + "\n")


_STEP_NUL = (b"ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nENDSEC;\nDATA;\n"
             b"#1=CARTESIAN_POINT('',(0.,0.\x00,0.));\nENDSEC;\nEND-ISO-10303-21;\n")

FILES38.update({
    "las_scale_zero": ("scale0.las", _las_scale_zero),
    "metres_csv": ("metres.csv", _metres),
    "step_nul": ("nul.step", _STEP_NUL),
    "job_deep": ("deep.job.json", "[" * 100_000),
    "scan_far_mark": ("farmark.csv", lambda path, good: (
        path.write_text(Path(good["design"]).read_text()),
        path.with_name("farmark.csv.mark.json").write_text('{"reference_mark_mm": [10000000, 0, 0]}'))),
    "job_big_int": ("bigint.job.json", lambda path, good: path.write_text(
        Path(good["job"]).read_text().replace('"thickness_mm": 20.0', '"thickness_mm": ' + "9" * 400, 1))),
    "press_big_int": ("bigint.toml", _PRESS.read_text().replace("rows = 16", "rows = " + "9" * 400)),
    "comma_decimals_6": ("comma6.csv", "".join(f"{x},0,{y},5,{(x * x) % 7},25\n" for x in range(-600, 601, 100)
                                               for y in range(-400, 401, 100))),
    "comma_decimals_4": ("comma4.csv", "".join(f"{x},{y},{(x * x) % 7},5\n" for x in range(-600, 601, 100)
                                               for y in range(-400, 401, 100))),
    "manifest_abs": ("abs.csv", "name,design,thickness_mm\n/tmp/elsewhere/P1,design.csv,20\n"),
    "manifest_dotdot": ("dotdot.csv", "name,design,thickness_mm\n../../P1,design.csv,20\n"),
    "manifest_7th": ("seven.csv", "name,design,flat,thickness_mm,material,springback\nP1,design.csv,,20,steel,no,x\n"),
    "manifest_newline": ("newline.csv", 'name,design,thickness_mm\n"P1\nP2",design.csv,20\n'),
    "manifest_thick": ("thick.csv", "name,design,thickness_mm\nP1,design.csv,1e6\n"),
    "ply_2e9_faces": ("faces.ply", ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                    "property float y\nproperty float z\nelement face 2000000000\n"
                                    "property list uchar int vertex_indices\nend_header\n"
                                    "0 0 0\n1000 0 0\n0 1000 0\n3 0 1 2\n")),
    "scan_3_points": ("three.xyz", "0 0 0\n1000 0 0\n0 1000 0\n"),
    "press_job_nan_axis": ("nanaxis.job.json", _edited("job", lambda d: d["punch_x_mm"].__setitem__(3, float("nan")))),
})


def _cases() -> list[dict]:
    cases = []
    plc = "tcp://127.0.0.1:9?unit=1"  # never connected: each job is refused before any connection
    for key, (_, _, words, again) in EDITS.items():
        name = f"job38_{key}"
        cases.append({"id": f"issue 38: {key} -> press (dry run)", "kind": "job38", "files": [name],
                      "args": ["press", "{" + name + "}"], "expect": words, "dry_run": True})
        cases.append({"id": f"issue 38: {key} -> press --plc", "kind": "job38", "files": [name],
                      "args": ["press", "{" + name + "}", "--plc", plc, "--yes"], "expect": words})
        if again:
            cases.append({"id": f"issue 38: {key}, sealed again -> press --press", "kind": "job38",
                          "files": [name + "_resealed"], "dry_run": True,
                          "args": ["press", "{" + name + "_resealed}", "--press", str(_PRESS)], "expect": again})
        cases.append({"id": f"issue 38: {key} -> panel --job", "kind": "job38", "files": [name],
                      "args": ["panel", "--job", "{" + name + "}", "--port", "1"], "expect": words})
    cases += [
        {"id": "issue 38: compare --job with a broken seal", "kind": "job38", "files": ["job38_pair_up_2"],
         "args": ["compare", "{design}", "{design}", "--job", "{job38_pair_up_2}"], "expect": [SEAL]},
        {"id": "issue 38: press with NaN punch positions", "kind": "job38", "files": ["press_job_nan_axis"],
         "args": ["press", "{press_job_nan_axis}"], "expect": ["nanaxis.job.json", "punch_x_mm[3] is nan"]},
        {"id": "issue 38: manifest plate name an absolute path", "kind": "batch", "files": ["manifest_abs"],
         "args": ["batch", "--manifest", "{manifest_abs}", "-o", "{tmp}/out"],
         "expect": ["abs.csv, line 2", "plate name '/tmp/elsewhere/P1' is not allowed"]},
        {"id": "issue 38: manifest plate name with ../", "kind": "batch", "files": ["manifest_dotdot"],
         "args": ["batch", "--manifest", "{manifest_dotdot}", "-o", "{tmp}/out"],
         "expect": ["dotdot.csv, line 2", "'../../P1'"]},
        {"id": "issue 38: manifest row with a 7th field", "kind": "batch", "files": ["manifest_7th"],
         "args": ["batch", "--manifest", "{manifest_7th}", "-o", "{tmp}/out"],
         "expect": ["seven.csv, line 2", "1 field(s) more than the header's 6 column(s)", "'x'"]},
        {"id": "issue 38: manifest plate name with a newline", "kind": "batch", "files": ["manifest_newline"],
         "args": ["batch", "--manifest", "{manifest_newline}", "-o", "{tmp}/out"],
         "expect": ["newline.csv, line 2", "plate name 'P1\\nP2' is not allowed"]},
        {"id": "issue 38: manifest thickness 1e6", "kind": "batch", "files": ["manifest_thick"],
         "args": ["batch", "--manifest", "{manifest_thick}", "-o", "{tmp}/out"],
         "expect": ["thick.csv, line 2", "thickness_mm 1e+06 mm is above the largest plate the press takes, 50 mm"]},
        {"id": "issue 38: batch --thickness 1e6", "kind": "batch",
         "args": ["batch", "{design}", "--thickness", "1e6", "-o", "{tmp}/out"],
         "expect": ["--thickness", "at most 50 mm, got 1000000.0 mm"]},
        {"id": "issue 38: PLY header with 2e9 faces -> compare", "kind": "points", "files": ["ply_2e9_faces"],
         "args": ["compare", "{design}", "{ply_2e9_faces}"],
         "expect": ["faces.ply", "announces 2,000,000,000 face element(s)", "only 32 bytes follow"]},
        {"id": "issue 38: scan of 3 points -> compare", "kind": "points", "files": ["scan_3_points"],
         "args": ["compare", "{design}", "{scan_3_points}"], "expect": ["three.xyz", "has 3 point(s)"]},
        {"id": "issue 38: scan of 3 points -> register", "kind": "points", "files": ["scan_3_points"],
         "args": ["register", "{scan_3_points}", "{design}"], "expect": ["three.xyz", "has 3 point(s)"]},
        {"id": "issue 38: compare --margin 1e9", "kind": "option",
         "args": ["compare", "{design}", "{design}", "--margin", "1e9"],
         "expect": ["--margin", "from 0 to 500 mm, got 1000000000.0 mm"]},
        {"id": "issue 38: compare --mark 10 km away", "kind": "option",
         "args": ["compare", "{design}", "{design}", "--mark", "10000000,0,0"],
         "expect": ["--mark 1e+07,0,0 lies", "mm outside the scan", "design.csv"]},
        {"id": "issue 38: a mark file 10 km away -> compare", "kind": "points", "files": ["scan_far_mark"],
         "args": ["compare", "{design}", "{scan_far_mark}"],
         "expect": ["the reference mark of the scan (its mark file or header) 1e+07,0,0 lies", "farmark.csv"]},
        {"id": "issue 38: a path longer than the system allows", "kind": "option",
         "args": ["fit", "{tmp}/" + "p" * 300 + ".csv"], "expect": ["characters) is too long for this system"]},
        {"id": "issue 38: a space in the PLC host -> press", "kind": "plc",
         "args": ["press", "{job}", "--plc", "tcp://pre ss:502"], "expect": ["'tcp://pre ss:502'", "space"]},
        {"id": "issue 38: a space in the PLC host -> status", "kind": "plc",
         "args": ["status", "--plc", "tcp://pre ss:502"], "expect": ["'tcp://pre ss:502'", "space"]},
        {"id": "issue 38: unfold -o ''", "kind": "option", "args": ["unfold", "{design}", "-o", ""],
         "expect": ["the output path is empty"]},
        {"id": "issue 38: panel --job truncated", "kind": "job38", "files": ["job_truncated"],
         "args": ["panel", "--job", "{job_truncated}", "--port", "1"], "expect": ["cut.job.json", "not valid JSON"]},
        {"id": "issue 38: LAS scale 0 -> compare", "kind": "points", "files": ["las_scale_zero"],
         "args": ["compare", "{design}", "{las_scale_zero}"], "expect": ["scale0.las", "scale factor(s) x 0"]},
        {"id": "issue 38: a metre file without --units -> plan", "kind": "points", "files": ["metres_csv"],
         "args": ["plan", "{metres_csv}", "{flat}", "--thickness", "20"],
         "expect": ["metres.csv: the plate is only 1.2 mm across", "--units m"]},
        {"id": "issue 38: a scan in metres without --scan-units -> compare", "kind": "points",
         "files": ["metres_csv"], "args": ["compare", "{design}", "{metres_csv}"],
         "expect": ["metres.csv: the plate is only 1.2 mm across (--scan-units mm)", "give --scan-units m"]},
        {"id": "issue 38: a metre file without --units -> unfold", "kind": "points", "files": ["metres_csv"],
         "args": ["unfold", "{metres_csv}", "-o", "{tmp}/flat.csv"],
         "expect": ["metres.csv: the plate is only 1.2 mm across", "--units m"]},
        {"id": "issue 38: a 0.3 mm plate (--scale) -> unfold", "kind": "points",
         "args": ["unfold", "{design}", "--scale", "0.00025", "-o", "{tmp}/flat.csv"],
         "expect": ["the plate is only 0.3 mm across", "--scale 0.00025"]},
        {"id": "issue 38: a STEP file with a NUL byte -> fit", "kind": "cad", "files": ["step_nul"],
         "args": ["fit", "{step_nul}"], "expect": ["nul.step, line 6", "NUL byte"]},
        {"id": "issue 38: decimal commas between commas (6 columns) -> plan", "kind": "points",
         "files": ["comma_decimals_6"], "args": ["plan", "{comma_decimals_6}", "{flat}", "--thickness", "20"],
         "expect": ["comma6.csv, line 1", "6 comma-separated columns and not one decimal point", "decimal commas"]},
        {"id": "issue 38: decimal commas in z only (4 columns) -> unfold", "kind": "points",
         "files": ["comma_decimals_4"], "args": ["unfold", "{comma_decimals_4}", "-o", "{tmp}/flat.csv"],
         "expect": ["comma4.csv, line 1", "4 comma-separated columns", "decimal commas"]},
        {"id": "issue 38: a job nested too deeply -> press", "kind": "job38", "files": ["job_deep"],
         "args": ["press", "{job_deep}"], "expect": ["deep.job.json", "nested too deeply"]},
        {"id": "issue 38: an integer of 400 digits in a job -> press", "kind": "job38", "files": ["job_big_int"],
         "args": ["press", "{job_big_int}"], "expect": ["bigint.job.json", "thickness_mm is Infinity"]},
        {"id": "issue 38: an integer of 400 digits in a press -> plan", "kind": "press", "files": ["press_big_int"],
         "args": ["plan", "{design}", "{flat}", "--thickness", "20", "--press", "{press_big_int}"],
         "expect": ["bigint.toml", "rows must be a finite number, got an integer of 400 digits"]},
        {"id": "issue 38: a device as the job -> press", "kind": "job38", "args": ["press", "/dev/zero"],
         "expect": ["/dev/zero is not a regular file"]},
        {"id": "issue 38: a device as the job -> panel", "kind": "job38", "args": ["panel", "--job", "/dev/zero"],
         "expect": ["/dev/zero is not a regular file"]},
        {"id": "issue 38: a device as the press -> plan", "kind": "press",
         "args": ["plan", "{design}", "{flat}", "--thickness", "20", "--press", "/dev/zero"],
         "expect": ["/dev/zero is not a press description"]},
        {"id": "issue 38: a device as the manifest -> batch", "kind": "batch",
         "args": ["batch", "--manifest", "/dev/zero", "-o", "{tmp}/out"],
         "expect": ["manifest /dev/zero is not a manifest: not a regular file"]},
        {"id": "issue 38: reseal without a reason", "kind": "option",
         "args": ["reseal", "{job}", "--reason", " "], "expect": ["--reason is empty"]},
    ]
    return cases


CASES38 = _cases()
