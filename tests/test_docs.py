"""Every name the docs give exists (see :mod:`docs_names` for what is checked and how).

Each ``docs/*.md`` and ``README.md`` is read against the installed package and the working tree;
a made-up name, path, command, option, call, link or section in a temporary markdown text is found;
the sections of the docs that the package's docstrings cite exist.
"""

import pytest
from docs_names import DOCS, ROOT, code_problems, doc_problems


@pytest.mark.parametrize("doc", DOCS, ids=[str(d.relative_to(ROOT)) for d in DOCS])
def test_every_name_a_doc_gives_exists(doc):
    problems = doc_problems(doc, doc.read_text())
    assert not problems, f"{doc.relative_to(ROOT)} names what does not exist:\n" + "\n".join(problems)


def test_every_section_of_the_docs_the_code_cites_exists():
    problems = code_problems()
    assert not problems, "the code cites sections the docs lack:\n" + "\n".join(problems)


MADE_UP = """# Made up

## A real heading

Real: `mppf.correct.model_step.model_step`, `mppf.loop.decide.decide(..., verdict=)`, `mppf/correct/step.py`,
`correct/step.py`, `tests/test_docs.py::test_every_name_a_doc_gives_exists`, `mppf loop --resume`, `--resume`,
`correct_step(...)`, the function `model_step`, `LoopSettings(max_cycles=3)`, `sqrt(x)`, [a](#a-real-heading).
`mppf.correct.compensate.model_correction`
`mppf.nowhere`
`mppf.correct.model_step.no_such_function(x)`
`mppf.loop.decide.decide(..., no_such_keyword=1)`
`mppf/correct/no_such.py`
`correct/no_such.py`
`no_such.py`
`test_no_such_thing`
`tests/test_docs.py::test_no_such_test`
`mppf loop --no-such-option`
`mppf no-such-command --json`
`--no-such-option`
`benchmarks/bench_loop.py --no-such-option`
`no_such_helper(x)`
the function `no_such_function`
`LoopSettings(no_such_field=1)`
`compensate(..., options=CompensateOptions(no_such_field=1))`
[a link](no-such.md)
[a link](#no-such-heading)
see "A real heading", and see "No-such section"
`docs/compare.md`, "No-such section" of another doc

```
mppf plan design.csv flat.csv --no-such-option 3   # a comment: mppf nothing --nothing
from mppf.correct import no_such_module
```
"""


def test_a_made_up_name_path_command_option_or_link_is_found(tmp_path):
    doc = tmp_path / "made-up.md"
    doc.write_text(MADE_UP)
    problems = doc_problems(doc, MADE_UP)
    flagged = sorted({int(problem.split(":")[0]) for problem in problems})
    made_up = [n for n, line in enumerate(MADE_UP.lower().splitlines(), 1)
               if any(word in line for word in ("no_such", "no-such", "nowhere", "model_correction"))]
    assert flagged == made_up, "\n".join(problems)
    assert len(problems) == len(made_up), "\n".join(problems)
    wrapped = doc_problems(doc, "Run `mppf loop design.csv --on-pressed 'x --y'\n--no-such-option 3` now.\n")
    assert [problem.split(":")[0] for problem in wrapped] == ["1"], wrapped
