"""The benchmark scripts run (in their tiny --quick mode) and agree with their reference."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _load(name):
    """Import ``benchmarks/<name>.py`` as a module."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        return __import__(name)
    finally:
        sys.path.pop(0)


def test_bench_fem_quick_runs_and_matches_reference():
    bench_fem = _load("bench_fem")
    out = bench_fem.main(["--quick"])
    assert out["sizes"] and out["pipeline"] is not None
    for size in out["sizes"]:
        for row in size["rows"]:
            assert row["finite"] and row["rel_df"] < 1e-10, row["name"]


def test_bench_springs_quick_runs_and_matches_reference(capsys):
    bench_springs = _load("bench_springs")
    out = bench_springs.main(["--quick"])
    assert out["scenes"], "no scene was measured"
    text = capsys.readouterr().out
    assert "reference" in text and "Baraff–Witkin" in text
    for scene in out["scenes"]:
        # physlab's implicit step and the independent reference agree on the new velocities
        assert scene["agreement"]["rel"] < 1e-6, scene["agreement"]


def test_bench_inbetween_quick_runs(capsys):
    bench_inbetween = _load("bench_inbetween")
    out = bench_inbetween.main(["--quick"])
    (row,) = out["rows"]
    assert set(row["stages"]) == {"template", "deform", "render", "flow+path", "blend"}
    assert row["flipped"] == 0 and row["handle_error_px"] < 1.0
    assert row["deform_gradient"] > 0
    assert "paper Table 2" in capsys.readouterr().out
    assert out["render_seconds"] > 0


def test_bench_inbetween_occluded_quick_runs(capsys):
    bench_inbetween = _load("bench_inbetween")
    out = bench_inbetween.main(["--occluded", "--quick"])
    (row,) = out["rows"]
    assert row["pair"] == "fold_arm" and row["occ"] == 1 and row["tried"] >= 2
    assert row["single"] > 0 and "Table 2" in capsys.readouterr().out


def test_bench_motion_quick_runs(real_data, capsys):
    bench_motion = _load("bench_motion")
    out = bench_motion.main(["--quick", "--threads", "1", "--repeats", "1"])
    assert out["base"]["windows_per_s"] > 0 and out["control"]["windows_per_s"] > 0
    assert set(out["bf16"]) == {"base", "control"}
    assert all(r["windows_per_s"] > 0 for r in out["bf16"].values())
    assert out["auto_precision"] in ("fp32", "bf16")
    assert set(out["dropout_windows_per_s"]) == {(k, ref) for k in ("base", "control")
                                                 for ref in (False, True)}
    assert all(v > 0 for v in out["dropout_windows_per_s"].values())
    assert out["seconds_control"] > 0 and out["seconds_reference"] > 0
    assert out["seconds_unfused"] > 0 and out["seconds_overlay"] > 0
    assert out["seconds_guided"] > 0 and all(t > 0 for t in out["seconds_variants"].values())
    printed = capsys.readouterr().out
    assert "RTX 4090" in printed and "torch.nn.Dropout" in printed


def test_bench_widgets_finds_every_lesson_widget_and_moves_controls_in_range():
    """Discovery from the lessons (no timing asserted): every `interact(` of every lesson is
    found with a callable callback, and each moved value lies inside its control's range."""
    import json
    import re

    bench = _load("bench_widgets")
    widgets = bench.discover()
    n_calls = 0
    for p in sorted((ROOT / "lessons").glob("[0-9][0-9]_*.ipynb")):
        nb = json.loads(p.read_text(encoding="utf-8"))
        n_calls += sum(len(re.findall(r"(?m)^\s*(?:\w+\s*=\s*)?interact\(", "".join(c["source"])))
                       for c in nb["cells"] if c["cell_type"] == "code")
    assert len(widgets) == n_calls >= 10
    for w in widgets:
        assert callable(w.callback) and w.controls, (w.lesson, w.cell)
        for name, c in w.controls.items():
            moved = c.moved()
            if c.kind == "dropdown":
                assert moved in c.options and moved != c.value, (w.name, name)
            else:
                assert c.lo - 1e-12 <= moved <= c.hi + 1e-12 and moved != c.value, (w.name, name)


def test_bench_widgets_quick_runs_and_reports(capsys, tmp_path):
    bench = _load("bench_widgets")
    out = bench.main(["--quick", "--json", str(tmp_path / "w.json")])
    assert {r["callback"] for r in out["rows"]} == {"stiff_spring_demo", "stability_demo"}
    assert all(r["warm"] > 0 for r in out["rows"]) and out["reference"] > 0
    text = capsys.readouterr().out
    assert "median" in text and "target" in text
    assert (tmp_path / "w.json").stat().st_size > 100
