"""Packaging promises: cheap import, no heavy modules, the README's two commands."""
import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_import_is_cheap_and_lazy():
    code = ("import sys, time; t = time.perf_counter(); import physlab, physlab.integrators, "
            "physlab.springs; dt = time.perf_counter() - t; "
            "print(dt); print([m for m in ('torch', 'pyvista', 'vtk', 'matplotlib') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    lines = out.strip().splitlines()
    assert lines[-1] == "[]", f"heavy modules imported by physlab core: {lines[-1]}"
    assert float(lines[0]) < 2.0  # generous: numpy + scipy cold start; 'import physlab' alone is ~1 ms


def test_import_time_of_physlab_itself():
    err = subprocess.run([sys.executable, "-X", "importtime", "-c", "import physlab"],
                         capture_output=True, text=True, check=True).stderr
    own = [int(m.group(1)) for m in re.finditer(r"import time:\s+(\d+) \|\s+\d+ \| physlab$", err, re.M)]
    assert own and own[0] < 500_000  # µs of physlab's own import time (< 0.5 s)


def test_readme_quick_start_is_exactly_two_commands():
    readme = (ROOT / "README.md").read_text()
    block = re.search(r"## Quick start.*?```(?:bash|sh)?\n(.*?)```", readme, re.S)
    assert block, "README needs a '## Quick start' section with a code block"
    cmds = [c for c in block.group(1).splitlines() if c.strip() and not c.strip().startswith("#")]
    assert cmds == ["make lab", "make test"]
    assert "make test" in (ROOT / ".ci" / "run").read_text()


def test_lessons_are_listed_in_readme_and_stored_executed():
    readme = (ROOT / "README.md").read_text()
    lessons = sorted((ROOT / "lessons").glob("[0-9][0-9]_*.ipynb"))
    assert len(lessons) >= 4
    for path in lessons:
        assert path.name in readme, f"{path.name} missing from the README's lesson list"
        nb = json.loads(path.read_text())
        assert nb["metadata"]["kernelspec"]["name"] == "python3"
        code = [c for c in nb["cells"] if c["cell_type"] == "code"]
        assert all(c.get("execution_count") for c in code), f"{path.name} is not stored executed"
        outputs = [o for c in code for o in c.get("outputs", [])]
        assert not [o for o in outputs if o["output_type"] == "error"], f"{path.name} stores an error"
        assert any("image/png" in o.get("data", {}) or "text/html" in o.get("data", {}) for o in outputs)
        assert any(w in "".join(c["source"]) for c in code for w in ("interact(", "SketchCanvas(")), \
            f"{path.name} has no widget"
        long = [c for c in code if len("".join(c["source"]).splitlines()) > 25]
        assert not long, f"{path.name}: code cells over 25 lines belong in physlab/"
