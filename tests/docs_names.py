"""What the docs name and whether it exists. For each ``docs/*.md`` and ``README.md``, :func:`doc_problems`
reads the code spans, fenced code blocks and links and checks (``tests/test_docs.py`` runs it):

- **dotted names** ``mppf.a.b.c`` (also ``from mppf.a import b`` in blocks): the longest importable
  module imported, the rest by ``getattr`` (a dataclass field or an attribute set on ``self`` counts);
  ``name(..., key=)`` needs a parameter ``key``;
- **paths** (from ``mppf/ drivers/ sim/ tests/ docs/ benchmarks/ examples/ .ci/``; in spans also inside
  a package, ``correct/step.py``, and a bare ``name.py`` or ``test_name`` anywhere in the tree),
  ``tests/x.py::test_y``, relative links with their ``#anchor``, and sections cited by title
  (``x.md, "Title"``, ``see "Title"``: a heading or bold label of that doc starts so);
- **commands and options**: ``mppf CMD ... --opt`` in a span or block line, asked of the click group
  :data:`mppf.cli.cli`; a lone ``--opt`` span must be an option of some command or ``benchmarks/``
  script, and ``benchmarks/x.py --opt`` one of that script;
- **unqualified callables**: a call span (``correct_step(...)``, ``Job.sha256()``; every call in it)
  or a name the text calls a function, method or class must be defined in ``mppf/``, ``drivers/``
  or ``sim/`` (by the syntax tree), its keywords among the parameters. Math (``sqrt(...)``, names
  of one or two letters, a span with `` = `` or `` <= ``) and built-ins are not code; a name whose
  first part is another installed module (``scipy.spatial``) is imported.
"""

from __future__ import annotations

import ast
import builtins
import dataclasses
import importlib
import importlib.util
import inspect
import re
from functools import cache
from pathlib import Path

import click

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
ROOTS = ("mppf", "drivers", "sim", "tests", "docs", "benchmarks", "examples", ".ci")  # a path's first folder
PACKAGE_DIRS = (ROOT / "mppf", ROOT / "drivers", ROOT / "sim")
MATH_NOTATION = {"sqrt", "mean", "std", "exp", "log", "sin", "cos", "tan", "atan2", "sum"}
OUTSIDE_OPTIONS = {"--strict-markers"}  # other programs' options the docs name alone in a span (pytest's)
SPAN = re.compile(r"(`+)(.+?)\1", re.DOTALL)  # a span may run over the lines of a paragraph
DOTTED = re.compile(r"(?<![\w./-])mppf(?:\.[A-Za-z_]\w*)+")
FROM_IMPORT = re.compile(r"^\s*from\s+(mppf[\w.]*)\s+import\s+\(?([\w\s,]+)\)?")
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
CALL = re.compile(r"^([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)\(")
NAMED = re.compile(r"^[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*$")
OPTION = re.compile(r"(?<![\w-])(--?[A-Za-z][\w-]*)")
COMMAND = re.compile(r"(?:^|(?<=[\s(`$]))mppf((?:\s+--[\w-]+)*)\s+([a-z][a-z-]*(?:\\?\|[a-z][a-z-]*)*)")
KINDS = r"(?:function|method|class|property|generator)"
# a section cited by its title: ``x.md, "Title"``, or ``see "Title"`` / ``("Title")`` in the same doc
SECTION_REF = re.compile(r"(?:\b([a-z][\w-]*\.md)\)?,?\s+(?:section\s+)?|\bsee\s+|\()\"([A-Z][a-z][^\"]*)\"")


def doc_parts(text: str) -> tuple[list[tuple[int, str, str, str]], list[tuple[int, str]], list[tuple[int, str]]]:
    """The code spans (line, span, text before, after; a span may run over lines of a paragraph),
    code-block lines (line, text; a line ending in ``\\`` joined with the next) and links (line,
    target) of a markdown text."""
    spans, blocks, links, fence, held, prose = [], [], [], None, "", []
    for number, line in enumerate(text.splitlines() + [""], 1):
        mark = re.match(r"^\s*(```|~~~)", line)
        if fence is None and (mark or not line.strip() or line.startswith("|")):
            spans_links(prose + ([(number, line)] if line.startswith("|") else []), spans, links)
            prose = []
        if mark and (fence is None or mark.group(1) == fence):
            fence = mark.group(1) if fence is None else None
        elif fence is not None:
            held += line.rstrip()
            if held.endswith("\\"):
                held = held[:-1] + " "
            else:
                blocks.append((number, held))
                held = ""
        elif line.strip() and not line.startswith("|"):
            prose.append((number, line))
    return spans, blocks, links


def spans_links(lines: list[tuple[int, str]], spans: list, links: list) -> None:
    """Add the code spans and links of one paragraph (numbered lines) to ``spans`` and ``links``."""
    if not lines:
        return
    text, first = "\n".join(line for _, line in lines), lines[0][0]
    for match in SPAN.finditer(text):
        head, tail = text[: match.start()], text[match.end():]
        span = re.sub(r"\s*\n\s*", " ", match.group(2)).strip()
        spans.append((first + head.count("\n"), span, head.rsplit("\n", 1)[-1], tail.split("\n", 1)[0]))
    plain = SPAN.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)
    for match in LINK.finditer(plain):
        links.append((first + plain[: match.start()].count("\n"), match.group(1)))
    unticked = text.replace("`", "")
    for match in SECTION_REF.finditer(unticked):  # a section by its title: (doc name or None, title)
        links.append((first + unticked[: match.start()].count("\n"), (match.group(1), match.group(2))))


def keywords(call: str) -> list[str]:
    """The keyword names at the first depth of the first call's parentheses in ``call``."""
    depth, names, start = 0, [], call.index("(")
    for match in re.finditer(r"[()\[\]]|(\w+)=(?!=)", call[start:]):
        token = match.group(0)
        if token in "([":
            depth += 1
        elif token in ")]":
            depth -= 1
            if depth == 0:
                break
        elif depth == 1:
            names.append(match.group(1))
    return names


def resolve(dotted: str):
    """The object a dotted name of the installed package names; raises LookupError if none."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        name = ".".join(parts[:cut])
        try:
            obj = importlib.import_module(name)
        except ModuleNotFoundError as error:
            if error.name and name.startswith(error.name) and error.name.split(".")[0] == parts[0]:
                continue
            raise
        for attribute in parts[cut:]:
            obj = attribute_of(obj, attribute, dotted)
        return obj
    raise LookupError(f"no module {parts[0]!r}")


def attribute_of(obj, attribute: str, dotted: str):
    """``getattr``, where a dataclass field or an attribute a class sets on ``self`` counts too."""
    if hasattr(obj, attribute):
        return getattr(obj, attribute)
    if inspect.isclass(obj):
        fields = {field.name for field in dataclasses.fields(obj)} if dataclasses.is_dataclass(obj) else set()
        annotated = {name for klass in obj.__mro__ for name in getattr(klass, "__annotations__", {})}
        try:
            source = inspect.getsource(obj)
        except (OSError, TypeError):
            source = ""
        if attribute in fields | annotated or re.search(rf"\bself\.{attribute}\s*(:[^=]+)?=", source):
            return None
    raise LookupError(f"{dotted}: {getattr(obj, '__name__', obj)!r} has no attribute {attribute!r}")


def check_call_keywords(obj, span: str, name: str) -> list[str]:
    """The keywords of the call in ``span`` that ``obj``'s signature does not take."""
    try:
        parameters = inspect.signature(obj).parameters
    except (TypeError, ValueError):
        return []
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values()):
        return []
    return [f"{name} takes no keyword {key!r}" for key in keywords(span) if key not in parameters]


def check_dotted(span: str, in_block: bool) -> list[str]:
    """Problems with the ``mppf.`` names in one span or block line."""
    names = DOTTED.findall(span)
    imported = FROM_IMPORT.match(span) if in_block else None
    if imported:
        names += [f"{imported.group(1)}.{n.strip()}" for n in imported.group(2).split(",") if n.strip()]
    problems = []
    for name in dict.fromkeys(names):
        try:
            obj = resolve(name)
        except LookupError as error:
            problems.append(f"{name} does not exist ({error})")
            continue
        if not in_block and span.startswith(name + "("):
            problems += check_call_keywords(obj, span, name)
    return problems


def path_problems(token: str, inside_packages: bool) -> list[str]:
    """Problems with one path-like token (nothing when it is not a path of the tree)."""
    path, _, test = token.strip("'\"").partition("::")
    if not re.fullmatch(r"[\w.-]+(/[\w.-]+)*/?", path) or "/" not in path or "://" in token:
        return []
    first = path.split("/")[0]
    if first in ("", ".", ".."):
        return []
    if first in ROOTS:
        bases = [ROOT]
    elif inside_packages and ((ROOT / "mppf" / first).is_dir() or (ROOT / "sim" / first).is_dir()):
        bases = [ROOT / "mppf", ROOT / "sim"]
    else:
        return []
    found = [base / path for base in bases if (base / path).exists()]
    if not found:
        return [f"path {path} does not exist"]
    if test and not re.search(rf"^\s*(async\s+)?def {re.escape(test)}\(", found[0].read_text(), re.MULTILINE):
        return [f"{path} has no test {test}"]
    return []


def check_paths(text: str, in_block: bool) -> list[str]:
    """Problems with the paths in one span or block line (a span of a bare ``name.py`` or ``test_x``: in the tree)."""
    if not in_block and re.fullmatch(r"\w+\.py|test_\w+", text) and text not in tree_names():
        return [f"no file or test {text} in mppf/, drivers/, sim/, tests/ or benchmarks/"]
    return [problem for token in text.split() for problem in path_problems(token, not in_block)]


@cache
def tree_names() -> frozenset[str]:
    """The Python files (with and without ``.py``) of the package, tests and benchmarks, and the test functions."""
    files = [path for folder in PACKAGE_DIRS + (ROOT / "tests", ROOT / "benchmarks") for path in folder.rglob("*.py")]
    tests = {name for path in files if path.name.startswith("test_")
             for name in re.findall(r"^\s*(?:async\s+)?def (test_\w+)", path.read_text(), re.MULTILINE)}
    return frozenset({path.name for path in files} | {path.stem for path in files} | tests)


@cache
def heading_anchors(path: Path) -> frozenset[str]:
    """The anchors of a markdown file's headings, as GitHub makes them."""
    anchors, fence = set(), False
    for line in path.read_text().splitlines():
        if re.match(r"^\s*(```|~~~)", line):
            fence = not fence
        elif not fence and re.match(r"^#{1,6}\s", line):
            title = re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower())
            anchors.add(title.replace(" ", "-"))
    return frozenset(anchors)


@cache
def section_titles(path: Path) -> tuple[str, ...]:
    """A markdown file's headings (without a leading number) and bold labels, lower case, no backticks."""
    text = path.read_text()
    titles = [re.sub(r"^\d+[a-z]?\.\s*", "", line.lstrip("#").strip()) for line in text.splitlines()
              if re.match(r"^#{1,6}\s", line)] + re.findall(r"\*\*([^*]+)\*\*", text)
    return tuple(re.sub(r"\s+", " ", title.replace("`", "")).lower() for title in titles)


def check_section(doc: Path, name: str | None, title: str) -> list[str]:
    """Problems with a section of ``name`` (None: of ``doc``) cited by its title."""
    cited = (ROOT / "docs" / name) if name and not (doc.parent / name).exists() else doc.parent / (name or doc.name)
    if not cited.exists():
        return [f"section \"{title}\" of {name}: {name} does not exist"]
    wanted = re.sub(r"\s+", " ", title).lower().rstrip("?:.")
    if not any(known.startswith(wanted) for known in section_titles(cited)):
        return [f"{cited.name} has no section \"{title}\" (no heading or bold label starts so)"]
    return []


def check_link(doc: Path, target: str | tuple[str | None, str]) -> list[str]:
    """Problems with one link target of ``doc`` (outside links are not followed), or a section cited."""
    if isinstance(target, tuple):
        return check_section(doc, *target)
    if re.match(r"^[a-z]+:", target):
        return []
    path, _, anchor = target.partition("#")
    linked = (doc.parent / path).resolve() if path else doc
    if not linked.exists():
        return [f"link {target}: {path} does not exist"]
    if anchor and linked.suffix == ".md" and anchor not in heading_anchors(linked):
        return [f"link {target}: {linked.name} has no heading with the anchor #{anchor}"]
    return []


@cache
def command_options() -> dict[str, frozenset[str]]:
    """Each ``mppf`` command's option names, asked of the click group (``""``: the group's own)."""
    from mppf.cli import cli

    context = click.Context(cli)
    def names(command) -> frozenset[str]:
        opts = {"--help", "-h"}
        for parameter in command.params:
            opts.update(parameter.opts + parameter.secondary_opts)
        return frozenset(o for o in opts if o.startswith("-"))
    options = {name: names(cli.get_command(context, name)) for name in cli.list_commands(context)}
    options[""] = names(cli) | {"--version"}
    return options


def check_options(span: str, in_block: bool) -> list[str]:
    """Problems with ``mppf CMD --opt``, ``benchmarks/x.py --opt`` or a lone ``--opt``."""
    options, problems = command_options(), []
    if in_block:
        span = re.split(r"(?:^|\s)#", span)[0]
    for match in COMMAND.finditer(span):
        tail = re.sub(r"\"[^\"]*\"|'[^']*'", "", re.split(r"\s#\s|&&|;|\bmppf\s", span[match.end():])[0])
        for option in OPTION.findall(match.group(1)):
            problems += [] if option in options[""] else [f"mppf has no option {option}"]
        for command in re.split(r"\\?\|", match.group(2)):
            if command not in options:  # flagged where the text is a command line, not prose
                problems += [f"mppf has no command {command!r}"] if re.match(r"\$?\s*mppf\s", span) else []
                continue
            problems += [f"mppf {command} has no option {o}" for o in OPTION.findall(tail)
                         if o not in options[command]]
    script = re.search(r"(benchmarks/\w+\.py)\s(.*)", span)
    if script and (ROOT / script.group(1)).is_file():
        source = (ROOT / script.group(1)).read_text()
        problems += [f"{script.group(1)} has no option {o}" for o in re.findall(r"(?<![\w-])(--[a-z][\w-]*)",
                     script.group(2)) if f'"{o}"' not in source]
    lone = re.fullmatch(r"(--[a-z][\w-]*)(=.*)?", span)
    if lone and not in_block and not known_option(lone.group(1)):
        problems.append(f"{lone.group(1)} is an option of no mppf command nor benchmark script")
    return problems


def known_option(option: str) -> bool:
    """Whether an option alone in a span belongs to some command or benchmark script."""
    return option in OUTSIDE_OPTIONS or any(option in opts for opts in command_options().values()) or any(
        f'"{option}"' in script.read_text() for script in (ROOT / "benchmarks").glob("*.py"))


@cache
def definitions() -> dict[str, frozenset[str] | None]:
    """Every name defined in the package's source, with the keywords it takes (None: any): a function
    or method its parameters, a class its annotated fields and ``__init__``'s parameters, a constant none."""
    defined: dict[str, set[str] | None] = {}
    def add(name: str, params: set[str] | None) -> None:
        if name not in defined or defined[name] is None or params is None:
            defined[name] = None if name in defined and defined[name] is None else params
        else:
            defined[name] = defined[name] | params
    for folder in PACKAGE_DIRS:
        for source in folder.rglob("*.py"):
            for node in ast.walk(ast.parse(source.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    args = node.args
                    named = args.posonlyargs + args.args + args.kwonlyargs
                    add(node.name, None if args.kwarg else {a.arg for a in named})
                elif isinstance(node, ast.ClassDef):
                    fields = {n.target.id for n in node.body if isinstance(n, ast.AnnAssign)
                              and isinstance(n.target, ast.Name)}
                    init = [n for n in node.body if isinstance(n, ast.FunctionDef) and n.name == "__init__"]
                    add(node.name, None if init and init[0].args.kwarg else fields | {
                        a.arg for n in init for a in n.args.args + n.args.kwonlyargs})
                elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                    for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                        if isinstance(target, ast.Name):
                            add(target.id, set())
                        elif isinstance(target, ast.Attribute) and getattr(target.value, "id", "") == "self":
                            add(target.attr, None)  # an attribute, maybe a callable: its keywords unknown
    return {name: None if params is None else frozenset(params) for name, params in defined.items()}


def check_unqualified(span: str, before: str, after: str) -> list[str]:
    """Problems with a span that calls or names a callable of the code without ``mppf.``.

    In a span that starts with a call, every call in it is checked (``f(..., options=G(k=...))``).
    """
    if span.startswith("mppf.") or re.search(r"\s(=|<=|>=|<|>)\s", span):  # an equation is math, not code
        return []
    if CALL.match(span):
        calls = re.finditer(r"(?<![\w.])([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)\(", span)
        return [problem for call in calls for problem in check_name(call.group(1), span[call.start():])]
    if NAMED.match(span) and (re.search(rf"\b{KINDS}\s*$", before) or re.match(rf"\s*{KINDS}\b", after)):
        return check_name(span, None)
    return []


def check_name(dotted: str, call: str | None) -> list[str]:
    """Problems with one unqualified name, called in ``call`` (the text from the name on) or not."""
    parts = dotted.split(".")
    last = parts[-1]
    if last in MATH_NOTATION or len(last) <= 2 or (len(parts) == 1 and hasattr(builtins, last)):
        return []
    if parts[0] not in definitions() and importlib.util.find_spec(parts[0]) is not None:
        try:
            resolve(dotted)
        except (LookupError, ImportError) as error:
            return [f"{dotted} does not exist ({error})"]
        return []
    if last not in definitions():
        return [f"{dotted} is defined nowhere in mppf/, drivers/ or sim/"]
    params = definitions()[last]
    if call and params is not None:
        return [f"{dotted} takes no keyword {key!r}" for key in keywords(call) if key not in params]
    return []


def code_problems() -> list[str]:
    """The sections of ``docs/`` that the package's source cites (``docs/x.md``, "Title") and the docs lack."""
    problems = []
    for folder in PACKAGE_DIRS:
        for source in sorted(folder.rglob("*.py")):
            text = re.sub(r"\s*\n\s*#?\s*", " ", source.read_text().replace("`", ""))  # comments wrapped too
            for match in re.finditer(r"\bdocs/([\w-]+\.md),?\s+(?:section\s+)?\"([A-Z][^\"]*)\"", text):
                found = check_section(ROOT / "docs" / "index.md", match.group(1), match.group(2))
                problems += [f"{source.relative_to(ROOT)}: {problem}" for problem in found]
    return problems


def doc_problems(doc: Path, text: str) -> list[str]:
    """Every name, path, command, option and link in a markdown text that does not exist."""
    spans, blocks, links = doc_parts(text)
    problems = []
    for number, span, before, after in spans:
        found = check_dotted(span, False) + check_paths(span, False) + check_options(span, False)
        found += check_unqualified(span, before, after)
        problems += [f"{number}: `{span}`: {problem}" for problem in found]
    for number, line in blocks:
        found = check_dotted(line, True) + check_paths(line, True) + check_options(line, True)
        problems += [f"{number}: {line.strip()}: {problem}" for problem in found]
    for number, target in links:
        problems += [f"{number}: {problem}" for problem in check_link(doc, target)]
    return problems
