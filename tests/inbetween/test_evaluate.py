"""Ground-truth evaluation and the real-drawing check (physlab.inbetween.evaluate)."""
import json

import numpy as np
import pytest

from physlab.inbetween import inbetween_benchmark
from physlab.inbetween import evaluate


@pytest.fixture(scope="module")
def rows():
    pairs = inbetween_benchmark(size=128)
    pick = [next(p for p in pairs if p.kind == "tight"), next(p for p in pairs if p.kind == "far")]
    return evaluate.evaluate_pairs(pick, n_frames=5, progress=False)


def test_rows_and_summary(rows):
    assert len(rows) == 2 * len(evaluate.METHODS)
    for r in rows:
        for m in evaluate.METRICS:
            assert np.isfinite(r[f"{m}_mid"]) and np.isfinite(r[f"{m}_all"])
    summary = evaluate.summarize(rows)
    assert set(summary) == {(k, m) for k in ("far", "tight", "all") for m in evaluate.METHODS}
    assert summary["all", "physlab"]["n"] == 2
    far = {m: summary["far", m] for m in evaluate.METHODS}
    # the skeletal pipeline beats both image-only baselines by a wide margin on a far pair
    for base in ("cross_dissolve", "flow"):
        assert far["physlab"]["psnr_all"] > far[base]["psnr_all"] + 3
        assert far["physlab"]["cd_all"] < far[base]["cd_all"]
    table = evaluate.format_table(summary)
    assert table.count("\n") == 1 + 3 * len(evaluate.METHODS)
    assert "*" in table


def test_score_frames_identity_and_errors():
    rng = np.random.default_rng(0)
    truth = rng.uniform(0, 1, (5, 32, 32, 3)).astype(np.float32)
    s = evaluate.score_frames(truth, truth)
    assert s["psnr_mid"] == np.inf and s["ssim_all"] == pytest.approx(1.0) and s["cd_all"] == 0
    with pytest.raises(ValueError, match="≥ 3 frames"):
        evaluate.score_frames(truth[:2], truth[:2])


def test_cli_writes_table(tmp_path, capsys):
    assert evaluate.main(["--size", "128", "--frames", "5", "--pairs", "1", "--no-progress",
                          "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "physlab" in out and "LPIPS not computed" in out
    rows = json.loads((tmp_path / "rows.json").read_text())
    assert {r["method"] for r in rows} == set(evaluate.METHODS)
    assert (tmp_path / "table.md").is_file() and (tmp_path / "pairs" / f"{rows[0]['pair']}.png").is_file()


def test_real_animated_drawing_no_flips(real_data):
    r = evaluate.animated_drawing_inbetween("char2", n_frames=5)
    assert r["flipped"] == 0
    assert r["max_handle_error_px"] < 1.5
    res = r["result"]
    assert res.frames.shape[0] == 5 and res.frames.shape[-1] == 4
    # the keys are the drawing posed at the two BVH frames, and the poses differ
    assert np.abs(r["skeletons"][0].xy - r["skeletons"][-1].xy).max() > 20
