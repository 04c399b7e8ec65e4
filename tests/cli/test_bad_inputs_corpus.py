"""The bad-input corpus (data only; run by ``test_bad_inputs.py``).

:data:`FILES`: key -> (file name, content): text, bytes, None (missing) or ``make(path, good)``.
:data:`CASES`: dicts with ``id``, ``kind``, ``args`` (``{key}`` = a file of :data:`FILES`,
``{design}`` ``{flat}`` ``{press}`` ``{job}`` ``{history}`` ``{tmp}`` = good inputs and the
case's folder), ``files`` (keys to write) and ``expect`` (words the message must hold).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

_XYZ = [(100.0 * i, 50.0 * j, 0.01 * i * j) for i in range(8) for j in range(8)]


def _lines(fmt: str, sep: str = ",", decimal: str = ".") -> str:
    rows = [sep.join(f"{v:.3f}".replace(".", decimal) for v in p) for p in _XYZ]
    return fmt + "\n".join(rows) + "\n"


def _folder(path: Path, good) -> None:
    path.mkdir()


def _stl_triangle(*vertices) -> bytes:
    return struct.pack("<12fH", 0.0, 0.0, 1.0, *[c for v in vertices for c in v], 0)


def _job_edit(edit):
    def make(path: Path, good) -> None:
        doc = json.loads(Path(good["job"]).read_text())
        edit(doc)
        path.write_text(json.dumps(doc))
    return make


def _press_text(**changes) -> str:
    text = Path(__file__).resolve().parents[2].joinpath("mppf", "examples", "press.toml").read_text()
    for old, new in changes.items():
        old_line = next(line for line in text.splitlines() if line.split("=")[0].strip() == old)
        text = text.replace(old_line, new)
    return text


def _set_first_stroke(value):
    def edit(doc):
        row = next(r for r in doc["steps"][0]["upper_mm"] if any(v is not None for v in r))
        row[next(i for i, v in enumerate(row) if v is not None)] = value
    return edit


FILES = {
    # point files
    "missing_csv": ("missing.csv", None),
    "empty_csv": ("empty.csv", ""),
    "blank_csv": ("blank.csv", "\n\n   \n"),
    "header_only_csv": ("header.csv", "x,y,z\n# exported by nothing\n"),
    "semicolon_csv": ("semicolon.csv", _lines("x;y;z\n", sep=";")),
    "semicolon_comma_csv": ("excel.csv", _lines("X;Y;Z\n", sep=";", decimal=",")),
    "tab_comma_txt": ("tabs.txt", _lines("", sep="\t", decimal=",")),
    "space_comma_xyz": ("spaces.xyz", _lines("", sep=" ", decimal=",")),
    "utf16_csv": ("unicode.csv", _lines("x,y,z\n").encode("utf-16")),
    "utf16le_csv": ("unicode-le.csv", _lines("x,y,z\n").encode("utf-16-le")),
    "junk_csv": ("junk.csv", bytes(range(256)) * 8),
    "nul_csv": ("nul.csv", b"1,2,3\n4,5,\x006\n"),
    "control_csv": ("control.csv", ("1,2,3\n" + "\x01\x02\x03\x04" * 50).encode("latin-1")),
    "word_csv": ("word.csv", "1,2,3\n4,five,6\n7,8,9\n"),
    "two_columns_csv": ("flat2d.csv", "1,2\n3,4\n5,6\n"),
    "ragged_csv": ("ragged.csv", "1,2,3\n4,5,6,7\n8,9,10\n"),
    "nan_csv": ("nan.csv", "1,2,3\n4,nan,6\n7,8,9\n"),
    "inf_csv": ("inf.csv", "1,2,3\n4,5,inf\n7,8,9\n"),
    "header_middle_csv": ("header-middle.csv", "1,2,3\nx,y,z\n4,5,6\n"),
    "quoted_csv": ("quoted.csv", '"x","y","z"\n"1","2","3"\n'),
    "html_csv": ("download.csv", "<html><body>Sign in to download</body></html>\n"),
    "folder_csv": ("folder.csv", _folder),
    "dat_file": ("points.dat", "1 2 3\n4 5 6\n"),
    "no_suffix": ("points", "1 2 3\n4 5 6\n"),
    "text_ply": ("points.ply", "1,2,3\n4,5,6\n"),
    "broken_ply": ("broken.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n"),
    "ply_no_z": ("noz.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                            "end_header\n1 2\n3 4\n"),
    "truncated_ply": ("truncated.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 100\n"
                                       b"property float x\nproperty float y\nproperty float z\nend_header\n"
                                       + b"\x00" * 40),
    "markup_csv": ("P3[rev2].csv", None),
    "bracket_missing_csv": ("[bold]design[/].csv", None),
    # meshes
    "obj_zero_based": ("zero.obj", "v 0 0 0\nv 100 0 0\nv 0 100 0\nv 100 100 0\nf 0 1 2\nf 1 3 2\n"),
    "obj_empty": ("empty.obj", ""),
    "obj_text_points": ("points.obj", "1,2,3\n4,5,6\n"),
    "stl_truncated": ("truncated.stl", b"\x00" * 80 + struct.pack("<I", 10)
                      + _stl_triangle((0, 0, 0), (100, 0, 0), (0, 100, 0)) * 3),
    "stl_short": ("short.stl", b"\x00" * 40),
    "stl_no_endsolid": ("cut.stl", "solid plate\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 100 0 0\n"
                                   "vertex 0 100 0\nendloop\nendfacet\n"),
    "stl_no_facets": ("nofacet.stl", "solid plate\nendsolid plate\n"),
    "stl_nan": ("nan.stl", b"\x00" * 80 + struct.pack("<I", 1)
                + _stl_triangle((0, 0, 0), (float("nan"), 0, 0), (0, 100, 0))),
    "stl_text_points": ("points.stl", "1,2,3\n4,5,6\n"),
    # press files
    "press_missing": ("missing.toml", None),
    "press_empty": ("empty.toml", ""),
    "press_not_toml": ("broken.toml", "name = = 'press'\n[matrix\n"),
    "press_no_matrix": ("nomatrix.toml", "name = 'press'\n"),
    "press_rows_zero": ("rows0.toml", _press_text(rows="rows = 0")),
    "press_rows_text": ("rowstext.toml", _press_text(rows='rows = "sixteen"')),
    "press_pitch_negative": ("pitch.toml", _press_text(pitch_x_mm="pitch_x_mm = -150.0")),
    "press_pitch_nan": ("pitchnan.toml", _press_text(pitch_y_mm="pitch_y_mm = nan")),
    "press_speed_zero": ("speed.toml", _press_text(speed_mm_s="speed_mm_s = 0.0")),
    "press_tip_negative": ("tip.toml", _press_text(tip_radius_mm="tip_radius_mm = -60.0")),
    "press_json": ("press.json", '{"name": "press"}'),
    "press_binary": ("binary.toml", bytes(range(256))),
    "press_other_shape": ("small.toml", _press_text(rows="rows = 8", cols="cols = 12")),
    "press_markup_name": ("markup.toml", _press_text(name='name = "MPP [/] press"', rows="rows = 8")),
    # job files
    "job_missing": ("missing.job.json", None),
    "job_empty": ("empty.job.json", ""),
    "job_not_json": ("broken.job.json", "{'steps': [1, 2"),
    "job_array": ("array.job.json", "[1, 2, 3]"),
    "job_empty_object": ("object.job.json", "{}"),
    "job_version": ("version.job.json", _job_edit(lambda d: d.update(format=99))),
    "job_tampered": ("tampered.job.json", _job_edit(_set_first_stroke(123.456))),
    "job_nan": ("nan.job.json", _job_edit(_set_first_stroke("nan"))),
    "job_no_steps": ("nosteps.job.json", _job_edit(lambda d: d.update(steps=[]))),
    "job_truncated": ("cut.job.json", lambda path, good: path.write_text(Path(good["job"]).read_text()[:500])),
    # other
    "not_sqlite": ("history.sqlite.txt", "this is not a database\n"),
    "a_file": ("scans.txt", "not a folder\n"),
}

POINT_KINDS = {  # key: words of the message
    "missing_csv": ["missing.csv", "not found"], "empty_csv": ["empty.csv", "empty"],
    "blank_csv": ["blank.csv", "empty"], "header_only_csv": ["header.csv", "no numeric data"],
    "semicolon_csv": ["semicolon.csv", "semicolons"], "semicolon_comma_csv": ["excel.csv", "decimal commas"],
    "tab_comma_txt": ["tabs.txt", "decimal commas"], "space_comma_xyz": ["spaces.xyz", "decimal commas"],
    "utf16_csv": ["unicode.csv", "UTF-16"], "utf16le_csv": ["unicode-le.csv", "UTF-16"],
    "junk_csv": ["junk.csv", "binary"], "nul_csv": ["nul.csv", "binary"], "control_csv": ["control.csv", "binary"],
    "word_csv": ["word.csv", "line 2", "'five'"], "two_columns_csv": ["flat2d.csv", "2 column(s)"],
    "ragged_csv": ["ragged.csv", "line 2", "4 column(s)"], "nan_csv": ["nan.csv", "line 2", "NaN"],
    "inf_csv": ["inf.csv", "line 2", "'inf'"], "header_middle_csv": ["header-middle.csv", "line 2"],
    "quoted_csv": ["quoted.csv", "double quotes"], "html_csv": ["download.csv", "no numeric data"],
    "folder_csv": ["folder.csv", "is a directory"], "dat_file": ["points.dat", "unknown file type"],
    "no_suffix": ["points", "unknown file type"], "text_ply": ["points.ply", "not a PLY file"],
    "broken_ply": ["broken.ply", "PLY"], "ply_no_z": ["noz.ply", "z"], "truncated_ply": ["truncated.ply", "PLY"],
    "markup_csv": ["P3[rev2].csv", "not found"], "bracket_missing_csv": ["[bold]design[/].csv", "not found"],
}
MESH_KINDS = {
    "obj_zero_based": ["zero.obj", "vertex index 0", "line 5"], "obj_empty": ["empty.obj", "empty"],
    "obj_text_points": ["points.obj", "OBJ"], "stl_truncated": ["truncated.stl", "10 triangles", "truncated"],
    "stl_short": ["short.stl", "too short"], "stl_no_endsolid": ["cut.stl", "endsolid"],
    "stl_no_facets": ["nofacet.stl", "facet"], "stl_nan": ["nan.stl", "NaN"],
    "stl_text_points": ["points.stl", "STL"],
}
PRESS_KINDS = {
    "press_missing": ["missing.toml"], "press_empty": ["empty.toml"], "press_not_toml": ["broken.toml"],
    "press_no_matrix": ["nomatrix.toml", "matrix"], "press_rows_zero": ["rows0.toml", "rows"],
    "press_rows_text": ["rowstext.toml", "rows", "sixteen"], "press_pitch_negative": ["pitch.toml", "pitch_x_mm"],
    "press_pitch_nan": ["pitchnan.toml", "pitch_y_mm"], "press_speed_zero": ["speed.toml", "speed_mm_s"],
    "press_tip_negative": ["tip.toml", "tip_radius_mm"], "press_json": ["press.json"],
    "press_binary": ["binary.toml"],
}
JOB_KINDS = {
    "job_missing": ["missing.job.json"], "job_empty": ["empty.job.json"], "job_not_json": ["broken.job.json"],
    "job_array": ["array.job.json"], "job_empty_object": ["object.job.json"], "job_version": ["version.job.json"],
    "job_tampered": ["tampered.job.json"], "job_nan": ["nan.job.json"], "job_no_steps": ["nosteps.job.json"],
    "job_truncated": ["cut.job.json"],
}
DRY_RUN_JOBS = {"job_tampered"}
"""Jobs whose refusal needs the (simulated) PLC: the one job validator runs against it, before any write."""
BAD_URLS = {
    "http": "http://press:80", "no host": "tcp://", "port out of range": "tcp://press:99999",
    "unit 0": "tcp://press:502?unit=0", "unit text": "tcp://press:502?unit=one",
    "unknown key": "tcp://press:502?speed=9",
    "no device": "rtu://", "no scheme": "press.local:502", "negative timeout": "tcp://press:502?timeout=-1",
    "fragment": "tcp://press:502#main", "bad parity": "rtu:///dev/ttyUSB0?parity=X",
}

_LOOP = ["--press", "{press}", "--thickness", "20", "--history", "{history}"]


def _point_cases() -> list[dict]:
    cases = []
    for key, words in {**POINT_KINDS, **MESH_KINDS}.items():
        kind = "points" if key in POINT_KINDS else "mesh"
        uses = {
            "fit": ["fit", "{" + key + "}"],
            "unfold": ["unfold", "{" + key + "}", "-o", "{tmp}/flat.csv"],
            "plan design": ["plan", "{" + key + "}", "{flat}", "--thickness", "20"],
            "loop design": ["loop", "{" + key + "}", "{flat}", *_LOOP],
        }
        if kind == "points":
            uses.update({
                "plan flat": ["plan", "{design}", "{" + key + "}", "--thickness", "20", "-o", "{tmp}/job.json"],
                "loop flat": ["loop", "{design}", "{" + key + "}", *_LOOP],
                "unfold json": ["unfold", "{" + key + "}", "-o", "{tmp}/flat.csv", "--json"],
            })
        for use, args in uses.items():
            cases.append({"id": f"{FILES[key][0]} ({key}) -> {use}", "kind": kind, "args": args, "files": [key],
                          "expect": words})
    return cases


def _file_cases() -> list[dict]:
    cases = []
    for key, words in PRESS_KINDS.items():
        for use, args in {
            "plan": ["plan", "{design}", "{flat}", "--thickness", "20", "--press", "{" + key + "}"],
            "loop": ["loop", "{design}", "{flat}", "--press", "{" + key + "}", "--thickness", "20", "--history",
                     "{history}"],
            "sim": ["sim", "--press", "{" + key + "}", "--duration", "0.1"],
            "press": ["press", "{job}", "--press", "{" + key + "}"],
        }.items():
            cases.append({"id": f"{FILES[key][0]} -> {use}", "kind": "press", "args": args, "files": [key],
                          "expect": words})
    for key, words in JOB_KINDS.items():
        for use, args in {"press": ["press", "{" + key + "}"],
                          "unfold --job": ["unfold", "{design}", "-o", "{tmp}/flat.dxf", "--job",
                                           "{" + key + "}"]}.items():
            cases.append({"id": f"{FILES[key][0]} -> {use}", "kind": "job", "args": args, "files": [key],
                          "expect": words, "dry_run": key in DRY_RUN_JOBS and use == "press"})
    for name, url in BAD_URLS.items():
        for use, args in {"press": ["press", "{job}", "--plc", url], "status": ["status", "--plc", url],
                          "stop": ["stop", "--plc", url], "reset": ["reset", "--plc", url]}.items():
            cases.append({"id": f"PLC URL {name} -> {use}", "kind": "plc", "args": args, "expect": [url]})
    for name in ("http", "unit 0", "no scheme"):
        cases.append({"id": f"PLC URL {name} -> loop", "kind": "plc", "expect": [BAD_URLS[name]],
                      "args": ["loop", "{design}", "{flat}", *_LOOP, "--plc", BAD_URLS[name]]})
    return cases


def _case(case_id: str, kind: str, args: list, expect: list, files=()) -> dict:
    return {"id": case_id, "kind": kind, "args": args, "expect": expect, "files": list(files)}


_RESUME = ["loop", "--resume", "--plate-id", "KEEP-1", "--history", "{history}"]

OPTION_CASES = [
    _case("loop --seed -1", "option", ["loop", "{design}", "{flat}", *_LOOP, "--seed", "-1"], ["--seed", "-1"]),
    _case("loop --time-scale 0", "option", ["loop", "{design}", "{flat}", *_LOOP, "--time-scale", "0"],
          ["--time-scale", "0"]),
    _case("loop --scan-timeout 0", "option", ["loop", "{design}", "{flat}", *_LOOP, "--scan-timeout", "0"],
          ["--scan-timeout", "0"]),
    _case("loop --scan-timeout nan", "option", ["loop", "{design}", "{flat}", *_LOOP, "--scan-timeout", "nan"],
          ["--scan-timeout", "nan"]),
    _case("loop --rescan-timeout 0", "option", ["loop", "{design}", "{flat}", *_LOOP, "--rescan-timeout", "0"],
          ["--rescan-timeout", "0"]),
    _case("loop --rescan-timeout -5", "option", ["loop", "{design}", "{flat}", *_LOOP, "--rescan-timeout", "-5"],
          ["--rescan-timeout", "-5"]),
    _case("loop --thickness 0", "option", ["loop", "{design}", "{flat}", "--press", "{press}", "--thickness", "0",
                                           "--history", "{history}"], ["--thickness", "0"]),
    _case("loop --thickness -5", "option", ["loop", "{design}", "{flat}", "--press", "{press}", "--thickness", "-5",
                                            "--history", "{history}"], ["--thickness", "-5"]),
    _case("loop --thickness 2000 (micrometres?)", "option", ["loop", "{design}", "{flat}", "--press", "{press}",
                                                             "--thickness", "2000", "--history", "{history}"],
          ["--thickness", "2000"]),
    _case("loop --thickness nan", "option", ["loop", "{design}", "{flat}", "--press", "{press}", "--thickness",
                                             "nan", "--history", "{history}"], ["--thickness", "nan"]),
    _case("loop --tolerance -1", "option", ["loop", "{design}", "{flat}", *_LOOP, "--tolerance", "-1"],
          ["tolerance", "-1"]),
    _case("loop --rms-tolerance 0", "option", ["loop", "{design}", "{flat}", *_LOOP, "--rms-tolerance", "0"],
          ["rms_tolerance", "0"]),
    _case("loop --max-cycles 0", "option", ["loop", "{design}", "{flat}", *_LOOP, "--max-cycles", "0"],
          ["max_cycles", "0"]),
    _case("loop --gain (retired: one correction)", "option", ["loop", "{design}", "{flat}", *_LOOP, "--gain", "1"],
          ["No such option", "--gain"]),
    _case("loop --margin -5", "option", ["loop", "{design}", "{flat}", *_LOOP, "--margin", "-5"], ["margin", "-5"]),
    _case("loop --material wood", "option", ["loop", "{design}", "{flat}", *_LOOP, "--material", "wood"],
          ["--material", "wood"]),
    _case("loop --seed text", "option", ["loop", "{design}", "{flat}", *_LOOP, "--seed", "one"], ["--seed", "one"]),
    _case("plate id with path traversal", "plate id",
          ["loop", "{design}", "{flat}", *_LOOP, "--plate-id", "../../../x"], ["plate id", "'../../../x'"]),
    _case("plate id with markup", "plate id", ["loop", "{design}", "{flat}", *_LOOP, "--plate-id", "B12[/]P3"],
          ["plate id", "'B12[/]P3'"]),
    _case("plate id with a space", "plate id", ["loop", "{design}", "{flat}", *_LOOP, "--plate-id", "B12 P3"],
          ["plate id", "'B12 P3'"]),
    _case("plate id absolute path", "plate id", ["loop", "{design}", "{flat}", *_LOOP, "--plate-id", "/etc/x"],
          ["plate id", "'/etc/x'"]),
    _case("plate id already recorded", "plate id", ["loop", "{design}", "{flat}", *_LOOP, "--plate-id", "KEEP-1"],
          ["KEEP-1", "already in the history"]),
    _case("loop --audit below a file", "option",
          ["loop", "{design}", "{flat}", *_LOOP, "--audit", "{a_file}/audit.sqlite"], ["--audit", "is a file"],
          ["a_file"]),
    _case("loop --audit is a folder", "option", ["loop", "{design}", "{flat}", *_LOOP, "--audit", "{tmp}"],
          ["--audit"]),
    _case("loop --resume unknown plate", "plate id", ["loop", "--resume", "--plate-id", "NOPE-9", "--history",
                                                      "{history}"], ["NOPE-9", "not in the history"]),
    _case("loop --resume with files", "option", ["loop", "{design}", "{flat}", "--resume", "--history",
                                                 "{history}"], ["--resume", "DESIGN"]),
    _case("loop without --press", "option", ["loop", "{design}", "{flat}", "--thickness", "20", "--history",
                                             "{history}"], ["--press"]),
    _case("loop --resume --seed -1", "option", [*_RESUME, "--seed", "-1"], ["--seed", "-1"]),
    _case("loop --resume --scan-timeout 0", "option", [*_RESUME, "--scan-timeout", "0"], ["--scan-timeout"]),
    _case("loop --resume --time-scale 0", "option", [*_RESUME, "--time-scale", "0"], ["--time-scale"]),
    _case("loop --history not sqlite", "option", ["loop", "--resume", "--history", "{not_sqlite}"],
          ["history.sqlite.txt"], ["not_sqlite"]),
    _case("scan folder missing", "scan folder", ["loop", "{design}", "{flat}", *_LOOP, "--scanner",
                                                 "{tmp}/no-scans"], ["no-scans"]),
    _case("scan folder is a file", "scan folder", ["loop", "{design}", "{flat}", *_LOOP, "--scanner", "{a_file}"],
          ["scans.txt"], ["a_file"]),
    _case("scan folder missing on resume", "scan folder", [*_RESUME, "--scanner", "{tmp}/gone"], ["gone"]),
    _case("plan --thickness 0", "option", ["plan", "{design}", "{flat}", "--thickness", "0"], ["thickness", "0"]),
    _case("plan --thickness nan", "option", ["plan", "{design}", "{flat}", "--thickness", "nan"],
          ["thickness", "nan"]),
    _case("plan --thickness -20", "option", ["plan", "{design}", "{flat}", "--thickness", "-20"],
          ["thickness", "-20"]),
    _case("plan --steps 0", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "--steps", "0"],
          ["--steps", "0"]),
    _case("plan --youngs -1", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "--youngs", "-1"],
          ["youngs", "-1"]),
    _case("plan --poisson 0.7", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "--poisson", "0.7"],
          ["poisson", "0.7"]),
    _case("plan --springback without material", "option", ["plan", "{design}", "{flat}", "--thickness", "20",
                                                            "--springback"], ["--springback"]),
    _case("plan -o in a missing folder", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "-o",
                                                    "{tmp}/missing/job.json"], ["job.json", "does not exist"]),
    _case("plan --plot .gif", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "--plot",
                                         "{tmp}/strokes.gif"], ["strokes.gif", ".gif"]),
    _case("plan --units km", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "--units", "km"],
          ["--units", "km"]),
    _case("plan --scale 0", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "--scale", "0"],
          ["--scale", "0"]),
    _case("plan --material wood", "option", ["plan", "{design}", "{flat}", "--thickness", "20", "--material",
                                             "wood"], ["--material", "wood"]),
    _case("plan without --thickness", "option", ["plan", "{design}", "{flat}"], ["--thickness"]),
    _case("unfold -o .gif", "option", ["unfold", "{design}", "-o", "{tmp}/flat.gif"], ["flat.gif", ".gif"]),
    _case("unfold -o missing folder", "option", ["unfold", "{design}", "-o", "{tmp}/no/flat.csv"],
          ["flat.csv", "does not exist"]),
    _case("unfold --margin -1", "option", ["unfold", "{design}", "-o", "{tmp}/flat.dxf", "--margin", "-1"],
          ["--margin", "-1"]),
    _case("unfold --scale -1", "option", ["unfold", "{design}", "-o", "{tmp}/flat.csv", "--scale", "-1"],
          ["--scale", "-1"]),
    _case("unfold --strain-limit -1", "option", ["unfold", "{design}", "-o", "{tmp}/flat.csv", "--strain-limit",
                                                 "-1"], ["--strain-limit", "-1"]),
    _case("unfold --strain-limit nan", "option", ["unfold", "{design}", "-o", "{tmp}/flat.csv", "--strain-limit",
                                                  "nan"], ["--strain-limit", "nan"]),
    _case("unfold --plot .bmp", "option", ["unfold", "{design}", "-o", "{tmp}/flat.csv", "--plot", "{tmp}/s.bmp"],
          ["s.bmp"]),
    _case("unfold without -o", "option", ["unfold", "{design}"], ["-o"]),
    _case("fit --degree 7", "option", ["fit", "{design}", "--degree", "7"], ["--degree", "7"]),
    _case("fit --kind nurbs", "option", ["fit", "{design}", "--kind", "nurbs"], ["--kind", "nurbs"]),
    _case("fit --smoothing -1", "option", ["fit", "{design}", "--kind", "spline", "--smoothing", "-1"],
          ["smoothing", "-1"]),
    _case("fit --units inch", "option", ["fit", "{design}", "--units", "inch"], ["--units", "inch"]),
    _case("sim --scan-ms 0", "option", ["sim", "--scan-ms", "0", "--duration", "0.1"], ["--scan-ms", "0"]),
    _case("sim --watchdog -1", "option", ["sim", "--watchdog", "-1", "--duration", "0.1"], ["--watchdog", "-1"]),
    _case("sim --time-scale 0", "option", ["sim", "--time-scale", "0", "--duration", "0.1"], ["--time-scale", "0"]),
    _case("sim --port 70000", "option", ["sim", "--port", "70000"], ["--port", "70000"]),
    _case("sim --rtu with --port", "option", ["sim", "--rtu", "pty", "--port", "5020"], ["--rtu"]),
    _case("sim --fault bogus", "option", ["sim", "--fault", "bogus", "--duration", "0.1"], ["bogus"]),
    _case("sim --unit 0", "option", ["sim", "--unit", "0"], ["--unit", "0"]),
    _case("sim --duration -1", "option", ["sim", "--duration", "-1"], ["--duration", "-1"]),
    _case("history missing file", "option", ["history", "--history", "{tmp}/nohistory.sqlite"],
          ["nohistory.sqlite", "does not exist"]),
    _case("history unknown plate", "plate id", ["history", "--history", "{history}", "--plate-id", "NOPE-1"],
          ["NOPE-1"]),
    _case("history not a database", "option", ["history", "--history", "{not_sqlite}"], ["history.sqlite.txt"],
          ["not_sqlite"]),
    _case("extract missing hull", "option", ["extract", "{tmp}/hull.igs", "-o", "{tmp}/plate.csv", "--x", "0", "1",
                                             "--girth", "0", "1"], ["hull.igs"]),
    _case("extract bad polygon", "option", ["extract", "{tmp}/hull.igs", "-o", "{tmp}/plate.csv", "--polygon",
                                            "1,2 3"], ["--polygon"]),
    _case("extract --x without --girth", "option", ["extract", "{tmp}/hull.igs", "-o", "{tmp}/plate.csv", "--x",
                                                    "0", "1"], ["--girth"]),
    _case("extract --spacing 0", "option", ["extract", "{tmp}/hull.igs", "-o", "{tmp}/plate.csv", "--spacing", "0"],
          ["--spacing", "0"]),
    _case("extract -o .gif", "option", ["extract", "{tmp}/hull.igs", "-o", "{tmp}/plate.gif"], ["plate.gif"]),
    _case("demo --plate unknown", "option", ["demo", "--out", "{tmp}/demo", "--plate", "NOPE"], ["NOPE"]),
    _case("demo --thickness 0", "option", ["demo", "--out", "{tmp}/demo", "--thickness", "0"],
          ["--thickness", "0"]),
    _case("demo --seed -1", "option", ["demo", "--out", "{tmp}/demo", "--seed", "-1"], ["--seed", "-1"]),
    _case("demo --time-scale 0", "option", ["demo", "--out", "{tmp}/demo", "--time-scale", "0"], ["--time-scale"]),
    _case("press --step 0", "option", ["press", "{job}", "--step", "0"], ["--step 0"]),
    _case("press --step 99", "option", ["press", "{job}", "--step", "99"], ["--step 99"]),
    _case("press --timeout 0", "option", ["press", "{job}", "--timeout", "0"], ["--timeout", "0"]),
    _case("press --timeout nan", "option", ["press", "{job}", "--timeout", "nan"], ["--timeout", "nan"]),
    _case("press --audit below a file", "option", ["press", "{job}", "--audit", "{a_file}/audit.sqlite"],
          ["--audit", "scans.txt", "is a file"], ["a_file"]),
    _case("press --audit is a folder", "option", ["press", "{job}", "--audit", "{tmp}"], ["--audit", "is a directory"]),
    _case("press of another shape", "press", ["press", "{job}", "--press", "{press_other_shape}"], ["small.toml"],
          ["press_other_shape"]),
    _case("press name with markup", "press", ["press", "{job}", "--press", "{press_markup_name}"],
          ["markup.toml"], ["press_markup_name"]),
    _case("press of another shape -> loop", "press", ["loop", "--resume", "--plate-id", "KEEP-1", "--history",
                                                       "{history}", "--press", "{press_other_shape}"],
          ["--press", "--resume"], ["press_other_shape"]),
    _case("status without --plc", "option", ["status"], ["no PLC given"]),
    _case("stop without --plc", "option", ["stop"], ["no PLC given"]),
    _case("reset without --plc", "option", ["reset"], ["no PLC given"]),
    _case("stop --plc without a value", "option", ["stop", "--plc"], ["--plc"]),
    _case("unknown command", "option", ["lopo"], ["lopo"]),
    _case("unknown option", "option", ["fit", "{design}", "--degre", "3"], ["--degre"]),
    _case("semicolon CSV -> unfold", "points", ["unfold", "{semicolon_csv}", "-o", "{tmp}/flat.csv"],
          ["semicolon.csv", "semicolons"], ["semicolon_csv"]),
    _case("truncated binary STL -> fit", "mesh", ["fit", "{stl_truncated}"], ["truncated.stl", "truncated"],
          ["stl_truncated"]),
]

CASES = _point_cases() + _file_cases() + OPTION_CASES
