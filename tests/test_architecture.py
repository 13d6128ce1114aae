"""The shape of the package (ARCHITECTURE.md): no import cycle inside ``physlab/``, no module
importing one of a higher layer, cheap top-level imports, and a current equation index."""
import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "physlab"
ARCH = ROOT / "ARCHITECTURE.md"


def modules():
    """Dotted module name -> file, for every module of the package."""
    out = {}
    for p in PKG.rglob("*.py"):
        parts = p.with_suffix("").relative_to(ROOT).parts
        out[".".join(parts[:-1] if p.name == "__init__.py" else parts)] = p
    return out


def import_graph():
    """module -> set of physlab modules it imports (anywhere in the file, lazy imports too).
    An import of a package's own submodule by the package (or of the package by its
    submodule) is not an edge: that is how packages re-export."""
    mods = modules()
    graph = {m: set() for m in mods}
    for m, p in mods.items():
        base = m.split(".") if p.name == "__init__.py" else m.split(".")[:-1]
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    mod = ".".join(base[:len(base) - node.level + 1]
                                   + ([node.module] if node.module else []))
                else:
                    mod = node.module or ""
                targets = [mod] + [f"{mod}.{a.name}" for a in node.names]
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != m and not t.startswith(m + ".") and not m.startswith(t + "."):
                    graph[m].add(t)
    return graph


def cycles(graph):
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def layers():
    """module prefix -> layer number, from the table between the layer markers of
    ARCHITECTURE.md (rows ``| n | name | `prefix`, `prefix` ... | what |``)."""
    text = ARCH.read_text(encoding="utf-8")
    table = text.split("<!-- layers:begin -->", 1)[1].split("<!-- layers:end -->", 1)[0]
    out = {}
    for row in table.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) >= 3 and cells[0].isdigit():
            for prefix in re.findall(r"`([\w.]+)`", cells[2]):
                out[prefix] = int(cells[0])
    return out


def layer_of(module, table):
    best = max((p for p in table if module == p or module.startswith(p + ".")), key=len,
               default=None)
    return None if best is None else table[best]


def test_the_graph_sees_lazy_imports():
    g = import_graph()
    assert "physlab.inbetween.characters" in g["physlab.datasets"]   # lazy, in __getattr__
    assert g["physlab.cli"]


def test_motion_sampling_does_not_depend_on_training():
    """Sampling reads checkpoints (motion.checkpoint) and the shared control losses
    (motion.guidance), never the training module."""
    g = import_graph()
    assert "physlab.motion.train" not in g["physlab.motion.sampling"]
    assert {"physlab.motion.checkpoint", "physlab.motion.guidance"} <= g["physlab.motion.sampling"]


def test_no_import_cycle():
    found = cycles(import_graph())
    assert not found, f"modules that import each other (directly or round a loop): {found}"


def test_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_every_module_has_a_layer_and_imports_only_its_own_or_lower_layers():
    table = layers()
    assert len(set(table.values())) >= 5, table
    graph = import_graph()
    missing = sorted(m for m in graph if layer_of(m, table) is None)
    assert not missing, f"modules without a layer in ARCHITECTURE.md: {missing}"
    upward = sorted(f"{m} (layer {layer_of(m, table)}) imports {t} (layer {layer_of(t, table)})"
                    for m, ts in graph.items() for t in ts
                    if layer_of(t, table) > layer_of(m, table))
    assert not upward, "imports against the layering:\n" + "\n".join(upward)


@pytest.mark.parametrize("module", ["physlab", "physlab.motion", "physlab.inbetween",
                                    "physlab.datasets", "physlab.physanimator"])
def test_top_level_imports_stay_cheap(module):
    code = (f"import sys, {module}; "
            "print(sorted(m for m in ('torch', 'pyvista', 'vtk', 'sentence_transformers') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]", f"import {module} loaded {out}"


def test_equation_index_is_current_and_complete():
    """ARCHITECTURE.md's equation index is what scripts/equation_index.py generates now, and
    every equation a lesson teaches is cited by some function."""
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import equation_index
    finally:
        sys.path.pop(0)
    if not equation_index.SEEDS.is_dir():
        pytest.skip(f"the source documents are not at {equation_index.SEEDS}")
    table = equation_index.build()
    assert equation_index.current_section(ARCH.read_text(encoding="utf-8")) == \
        equation_index.render(table), "stale: run `python scripts/equation_index.py --write`"
    gaps = equation_index.taught_but_uncited(table)
    assert not gaps, f"taught in a lesson but cited by no function: {gaps}"
