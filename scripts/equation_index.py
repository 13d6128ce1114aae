"""The equation index of ARCHITECTURE.md: every numbered equation of the four sources ->
the physlab functions whose docstrings or ``# Eq. (n)`` comments cite it -> the test files
that exercise those functions -> the lesson cells that teach it.

    python scripts/equation_index.py            # print the index (markdown)
    python scripts/equation_index.py --write    # rewrite the index section of ARCHITECTURE.md
    python scripts/equation_index.py --check    # exit 1 if ARCHITECTURE.md is stale, or if a
                                                # lesson teaches an equation no code cites

How a citation is attributed to a source: the text just before ``Eq. (n)`` / ``Eqs. (n)–(m)``
/ ``eq n`` on the same line names it (``Sketch2Anim``, ``PhysAnimator``, ``Brodt``,
``slides``); a citation naming another paper (DDPM, DDIM, Baraff–Witkin ...) is not one of
the four sources and is skipped; an unprefixed citation belongs to the source of its module
(:data:`MODULE_SOURCES`) or, in a lesson, of its lesson number (:data:`LESSON_SOURCES`).
"""
from __future__ import annotations

import argparse
import ast
import json
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SEEDS = REPO.parent / "shared" / "seeds"
ARCHITECTURE = REPO / "ARCHITECTURE.md"
BEGIN, END = "<!-- equation-index:begin -->", "<!-- equation-index:end -->"

#: source key -> (title, seed file, regex of an equation's number in the seed text)
SOURCES = {
    "slides": ("Course slides (Popa, COMP 477/6311)", "004_b49e6b3b92bd43c3.txt",
               r"\(eq ?(\d+)\)"),
    "PhysAnimator": ("PhysAnimator supplementary", "000_0a4fa540c2202b0e.txt",
                     r"\\quad \((\d+)\)"),
    "Brodt": ("Brodt & Bessmeltsev 2024, skeleton-driven inbetweening",
              "002_fe7ca6d9b1d4fa84.txt", r"\\tag\{(\d+)\}|T-junction, \((\d+)\)"),
    "Sketch2Anim": ("Sketch2Anim (Zhong et al. 2025)", "003_6d5655cd22abfc1d.txt",
                    r"\\quad \((\d+)\)"),
}
#: words before a citation that name one of the sources
SOURCE_WORDS = {"slides": ("slides", "slide"), "PhysAnimator": ("physanimator",),
                "Brodt": ("brodt", "bessmeltsev"), "Sketch2Anim": ("sketch2anim",)}
#: words before a citation that name another paper: not one of the four sources
OTHER_WORDS = ("ddpm", "ddim", "song", "ho et al", "ho &", "[bw]", "baraff", "witkin", "mdm",
               "slomo", "smith", "schaefer", "kabsch", "guo", "mld", "gmd", "rife", "lbfgs",
               "nocedal", "humanml3d", "nichol", "dhariwal", "salimans", "algorithm")
#: module path prefix -> default source of its unprefixed citations (first match wins)
MODULE_SOURCES = (("physlab/motion/diffusion", None),            # DDPM / DDIM: explicit only
                  ("physlab/integrators", "slides"), ("physlab/springs", "slides"),
                  ("physlab/linear_solver", "slides"), ("physlab/demos/basics", "slides"),
                  ("physlab/fem", "PhysAnimator"), ("physlab/physanimator", "PhysAnimator"),
                  ("physlab/demos/physanimator", "PhysAnimator"), ("physlab/render", "PhysAnimator"),
                  ("physlab/inbetween", "Brodt"), ("physlab/demos/inbetween", "Brodt"),
                  ("physlab/characters", "Brodt"),
                  ("physlab/motion", "Sketch2Anim"), ("physlab/demos/motion", "Sketch2Anim"))
#: lesson number -> source of its unprefixed citations
LESSON_SOURCES = {**dict.fromkeys(range(0, 4), "slides"),
                  **dict.fromkeys(range(4, 6), "PhysAnimator"),
                  **dict.fromkeys(range(6, 9), "Brodt"),
                  **dict.fromkeys(range(9, 12), "Sketch2Anim")}

CITE = re.compile(r"\b(?:Eqs?|eqs?|Equations?|equations?)\.?\s*\(?(\d+)\)?"
                  r"(?:\s*(?:[–-]|to|and|,)\s*\(?(\d+)\)?)?")


def seed_equations():
    """source -> sorted list of the equation numbers found in its seed text."""
    out = {}
    for key, (_, name, pattern) in SOURCES.items():
        text = (SEEDS / name).read_text(encoding="utf-8") if (SEEDS / name).is_file() else ""
        nums = {int(g) for m in re.finditer(pattern, text) for g in m.groups() if g}
        out[key] = sorted(nums)
    return out


def _source_of(before, default):
    """The source a citation belongs to, from the ~60 characters before it, or None."""
    low = before.lower()
    best, where = None, -1
    for key, words in SOURCE_WORDS.items():
        for w in words:
            i = low.rfind(w)
            if i > where:
                best, where = key, i
    for w in OTHER_WORDS:
        i = low.rfind(w)
        if i > where:
            return None
    return best or default


def citations(text, default):
    """``(source, number)`` pairs cited in ``text`` (ranges expanded, e.g. Eqs. (1)–(4))."""
    found = []
    for line in text.splitlines():
        for m in CITE.finditer(line):
            src = _source_of(line[max(0, m.start() - 60):m.start()], default)
            if src is None:
                continue
            a = int(m.group(1))
            b = int(m.group(2)) if m.group(2) else a
            if b < a or b - a > 20:
                b = a
            found += [(src, n) for n in range(a, b + 1)]
    return found


def _module_source(rel):
    for prefix, src in MODULE_SOURCES:
        if rel.startswith(prefix):
            return src
    return None


def code_citations():
    """(source, n) -> sorted list of ``module.qualname`` citing it (docstrings, comments)."""
    out = {}
    for path in sorted((REPO / "physlab").rglob("*.py")):
        rel = path.relative_to(REPO).as_posix()
        default = _module_source(rel)
        src_text = path.read_text(encoding="utf-8")
        lines = src_text.splitlines()
        tree = ast.parse(src_text)
        module = rel[:-3].replace("/", ".").removesuffix(".__init__")
        owner = [None] * (len(lines) + 2)                 # innermost def of every line

        def visit(node, prefix):
            """Top-level functions and classes, and the methods of classes (a nested helper
            belongs to the function around it)."""
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    if child.name.startswith("_") and child.name != "__call__":
                        continue                                   # private: not indexed
                    name = f"{prefix}{child.name}"
                    for i in range(child.lineno, (child.end_lineno or child.lineno) + 1):
                        owner[i] = name
                    if isinstance(child, ast.ClassDef):
                        visit(child, f"{name}.")

        visit(tree, "")
        for i, line in enumerate(lines, start=1):
            name = owner[i]
            if name is None:
                continue
            for key in citations(line, default):
                out.setdefault(key, set()).add(f"{module}.{name}")
    return {k: sorted(v) for k, v in out.items()}


def lesson_citations():
    """(source, n) -> sorted list of ``"NN cell k"`` whose markdown or code cites it."""
    out = {}
    for path in sorted((REPO / "lessons").glob("[0-9][0-9]_*.ipynb")):
        num = int(path.name[:2])
        nb = json.loads(path.read_text(encoding="utf-8"))
        for k, cell in enumerate(nb["cells"]):
            for key in citations("".join(cell["source"]), LESSON_SOURCES.get(num)):
                out.setdefault(key, set()).add((num, k))
    return {key: [f"{n:02d} cell {k}" for n, k in sorted(v)] for key, v in out.items()}


def test_files(qualnames):
    """Test files (relative paths) that import a function's module and use its name (for a
    method: its class's name)."""
    wanted = []
    for q in qualnames:
        parts = q.split(".")
        # module = the longest prefix that is a module path; the name = what follows it
        for cut in range(len(parts) - 1, 0, -1):
            mod = ".".join(parts[:cut])
            if (REPO / (mod.replace(".", "/") + ".py")).is_file() or \
                    (REPO / mod.replace(".", "/") / "__init__.py").is_file():
                wanted.append((mod, parts[cut]))
                break
    hits = []
    for path in sorted((REPO / "tests").rglob("test_*.py")):
        text = path.read_text(encoding="utf-8")
        for mod, name in wanted:
            parts = mod.split(".")
            # the module itself, or a package above it that re-exports the name or the module
            imports = re.search(rf"\b{re.escape(mod)}\b", text) or any(
                re.search(rf"from {re.escape('.'.join(parts[:k]))} import (\([^)]*|[^\n]*)"
                          rf"\b({re.escape(name)}|{parts[k]})\b", text)
                for k in range(1, len(parts)))
            if imports and re.search(rf"\b{re.escape(name)}\b", text):
                hits.append(path.relative_to(REPO).as_posix())
                break
    return hits


def build():
    """The index as a dict: source -> list of rows (n, functions, tests, lessons)."""
    seeds, code, lessons = seed_equations(), code_citations(), lesson_citations()
    table = {}
    for key in SOURCES:
        rows = []
        for n in seeds[key]:
            funcs = code.get((key, n), [])
            rows.append((n, funcs, test_files(funcs), lessons.get((key, n), [])))
        table[key] = rows
    return table


def render(table):
    out = ["Generated by `python scripts/equation_index.py --write` from the `Eq. (n)` "
           "citations in docstrings and comments; `tests/test_architecture.py` checks that it "
           "is current. \"—\" in *implemented by* means no function cites the equation.", ""]
    for key, rows in table.items():
        title, seed, _ = SOURCES[key]
        out += [f"### {title} (`{seed}`)", "",
                "| Eq. | implemented by | tested in | taught in |", "|---|---|---|---|"]
        for n, funcs, tests, lessons in rows:
            f = ", ".join(f"`{q.removeprefix('physlab.')}`" for q in funcs[:4]) or "—"
            if len(funcs) > 4:
                f += f" (+{len(funcs) - 4})"
            t = ", ".join(f"`{p.removeprefix('tests/')}`" for p in tests[:3]) or "—"
            if len(tests) > 3:
                t += f" (+{len(tests) - 3})"
            le = ", ".join(lessons[:3]) or "—"
            if len(lessons) > 3:
                le += f" (+{len(lessons) - 3})"
            out.append(f"| {n} | {f} | {t} | {le} |")
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def taught_but_uncited(table):
    """Equations a lesson teaches that no function cites: ``[(source, n, lessons)]``."""
    return [(key, n, lessons) for key, rows in table.items() for n, funcs, _, lessons in rows
            if lessons and not funcs]


def current_section(text):
    if BEGIN not in text or END not in text:
        raise ValueError(f"{ARCHITECTURE.name} has no {BEGIN} ... {END} section")
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip("\n") + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite ARCHITECTURE.md's index")
    ap.add_argument("--check", action="store_true", help="fail if stale or incomplete")
    args = ap.parse_args(argv)
    table = build()
    md = render(table)
    if args.write:
        text = ARCHITECTURE.read_text(encoding="utf-8")
        head, rest = text.split(BEGIN, 1)
        ARCHITECTURE.write_text(f"{head}{BEGIN}\n{md}{END}{rest.split(END, 1)[1]}",
                                encoding="utf-8")
        print(f"wrote the equation index to {ARCHITECTURE}")
    elif args.check:
        problems = []
        if current_section(ARCHITECTURE.read_text(encoding="utf-8")) != md:
            problems.append("ARCHITECTURE.md's equation index is stale: run "
                            "`python scripts/equation_index.py --write`")
        for key, n, lessons in taught_but_uncited(table):
            problems.append(f"{key} Eq. ({n}) is taught in lesson {', '.join(lessons)} but no "
                            f"function cites it")
        for p in problems:
            print(f"equation_index: error: {p}", file=sys.stderr)
        return 1 if problems else 0
    else:
        sys.stdout.write(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
