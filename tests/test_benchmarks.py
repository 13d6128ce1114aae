"""The benchmark scripts run (in their tiny --quick mode) and agree with their reference."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_bench_fem_quick_runs_and_matches_reference():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import bench_fem
    finally:
        sys.path.pop(0)
    out = bench_fem.main(["--quick"])
    assert out["sizes"] and out["pipeline"] is not None
    for size in out["sizes"]:
        for row in size["rows"]:
            assert row["finite"] and row["rel_df"] < 1e-10, row["name"]


def test_bench_springs_quick_runs_and_matches_reference(capsys):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import bench_springs
    finally:
        sys.path.pop(0)
    out = bench_springs.main(["--quick"])
    assert out["scenes"], "no scene was measured"
    text = capsys.readouterr().out
    assert "reference" in text and "Baraff–Witkin" in text
    for scene in out["scenes"]:
        # physlab's implicit step and the independent reference agree on the new velocities
        assert scene["agreement"]["rel"] < 1e-6, scene["agreement"]
