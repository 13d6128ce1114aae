"""Tests of physlab.motion.evaluate: the held-out table from smoke checkpoints (real clips,
text only, keypose + trajectory, single ControlNet), the test conditions, the CLI outputs and
the error cases."""
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from physlab.motion.dataset import BANDAI_NAMCO_ATTRIBUTION, condition_from_window
from physlab.motion.evaluate import (
    follow_slope,
    COLUMNS,
    MIN_T_R,
    ROW_NAMES,
    clip_metrics,
    eval_conditions,
    evaluate,
    format_table,
    EVALUATOR_COLUMNS,
    GUIDANCE_VARIANTS,
    held_out_windows,
    main,
)
from physlab.motion.sampling import build_condition
from physlab.motion.train import train

torch.set_num_threads(1)

SMOKE = {"smoke": True, "progress": False, "steps": 2, "num_threads": 1}
FAST = {"windows": 3, "steps": 2, "progress": False}


@pytest.fixture(scope="module")
def ckpts(real_data, tmp_path_factory):
    d = tmp_path_factory.mktemp("motion_evaluate")
    base = train(stage="base", out=str(d / "base.pt"), **SMOKE)["path"]
    control = train(stage="control", base_ckpt=str(base), out=str(d / "control.pt"),
                    **SMOKE)["path"]
    single = train(stage="control", base_ckpt=str(base), out=str(d / "single.pt"),
                   single_controlnet=True, **SMOKE)["path"]
    double = train(stage="control", base_ckpt=str(base), out=str(d / "double.pt"),
                   double_controlnet=True, **SMOKE)["path"]
    torch.set_num_threads(1)                         # train() sets its own thread count
    return {"base": base, "control": control, "single": single, "double": double}


@pytest.fixture(scope="module")
def rows(ckpts):
    # the smoke models' raw joints: the rigid-bone / floor projection of a barely trained
    # model's garbage would move the controlled joints (tested in test_body / the shipped model)
    return evaluate(ckpts["control"], single_controlnet=ckpts["single"], body_constraints=False,
                    double_controlnet=ckpts["double"], **FAST)


def test_all_rows_with_finite_numbers(rows):
    assert tuple(rows) == ROW_NAMES
    for name, r in rows.items():
        assert set(r) == set(COLUMNS) | set(EVALUATOR_COLUMNS) | {"n_clips",
                                                                 "r_precision_chance_top3"}, name
        assert r["n_clips"] == 3
        assert all(math.isfinite(r[k]) and r[k] >= 0 for k in COLUMNS), (name, r)
        assert all(math.isfinite(r[k]) and r[k] >= 0 for k in EVALUATOR_COLUMNS), (name, r)


def test_evaluator_columns_are_optional(ckpts):
    res = evaluate(ckpts["control"], evaluator=None, **FAST)
    assert all(set(r) == set(COLUMNS) | {"n_clips"} for r in res.values())
    assert "FID" not in format_table(res)


def test_real_clips_have_zero_control_error(rows):
    r = rows["real clips"]
    assert r["keypose_mpjpe_3d"] == 0.0 and r["trajectory_error_3d"] == 0.0
    assert r["seconds_per_clip"] == 0.0
    assert 0.0 <= r["foot_skating"] <= 1.0


def test_generated_rows_are_timed_and_differ_from_data(rows):
    for name in ROW_NAMES[1:]:
        assert rows[name]["seconds_per_clip"] > 0
        assert rows[name]["keypose_mpjpe_3d"] > 0 and rows[name]["trajectory_error_3d"] > 0


def test_single_controlnet_row_only_with_second_checkpoint(ckpts):
    r = evaluate(ckpts["control"], windows=1, steps=1, progress=False)
    assert tuple(r) == ROW_NAMES[:4]


def test_guidance_rows_land_closer_to_the_conditions(rows):
    """The inference guidance optimises the final x̂₀ towards the keypose and trajectories:
    even a smoke model then lands far closer than the networks alone."""
    for name in ("keypose + trajectory", "single ControlNet", "double ControlNet"):
        plain, guided = rows[name], rows[name + " + guidance"]
        assert guided["trajectory_error_3d"] < 0.5 * plain["trajectory_error_3d"], (plain, guided)
        assert guided["keypose_mpjpe_3d"] < 0.5 * plain["keypose_mpjpe_3d"], (plain, guided)


def test_evaluation_is_deterministic(ckpts, rows):
    again = evaluate(ckpts["control"], single_controlnet=ckpts["single"], body_constraints=False,
                     double_controlnet=ckpts["double"], **FAST)
    for name in ROW_NAMES:
        for k in COLUMNS:
            if k != "seconds_per_clip":
                assert again[name][k] == rows[name][k], (name, k)


def test_held_out_windows_and_conditions(real_data):
    data = held_out_windows(4)
    assert data["joints"].shape == (4, 40, 22, 3) and len(data["text"]) == 4
    assert len({(c, s) for c, s in zip(data["clip_id"], data["start"])}) == 4   # distinct
    conds = eval_conditions(data["joints"], seed=0)
    assert [c.key_frame for c in conds] == [0, 39, 0, 39]       # first / last alternate
    assert all(MIN_T_R <= c.t_r <= 40 for c in conds)
    again = eval_conditions(data["joints"], seed=0)
    assert all(np.array_equal(a.mask, b.mask) for a, b in zip(conds, again))
    # the generator receives exactly the condition layout of condition_from_window
    for c in conds:
        b = build_condition(**c.generator_kwargs())
        assert np.array_equal(b["traj_mask"], c.mask) and b["key_frame"] == c.key_frame
        assert np.allclose(b["trajectory"], c.trajectory) and np.allclose(b["keypose"], c.keypose)


def test_clip_metrics_analytic():
    """A motionless clip standing at the condition: no skating, no error, zero jerk."""
    x = np.zeros((2, 40, 22, 3))
    x[..., 1] = 0.5                                              # everything 0.5 m up
    conds = eval_conditions(x, seed=1)
    r = clip_metrics(x, conds, seconds=0.25)
    assert r["foot_skating"] == 0 and r["keypose_mpjpe_3d"] == 0
    assert r["trajectory_error_3d"] == 0 and r["pj"] == 0
    assert r["auj"] == pytest.approx(37 * 0.033031363)          # |0 - PJ_GT| over 37 frames
    shifted = clip_metrics(x + [0.0, 0.0, 0.1], conds)           # 10 cm off everywhere
    assert shifted["keypose_mpjpe_3d"] == pytest.approx(0.1)
    assert shifted["keypose_pose_3d"] == pytest.approx(0.0, abs=1e-12)   # same pose, moved
    assert shifted["trajectory_error_3d"] == pytest.approx(0.1)
    lifted = clip_metrics(x + [0.0, 0.03, 0.0], conds)            # 3 cm up: a pose error too
    assert lifted["keypose_pose_3d"] == pytest.approx(0.03)


def test_format_table_has_rows_and_attribution(rows):
    t = format_table(rows)
    assert all(f"| {name} |" in t for name in ROW_NAMES)
    assert BANDAI_NAMCO_ATTRIBUTION in t
    table = [line for line in t.splitlines() if line.startswith("|")]
    assert {line.count("|") for line in table} == {len(COLUMNS) + len(EVALUATOR_COLUMNS) + 2}


def test_guidance_variant_rows(ckpts):
    """Table A3's analogue: per-step guidance rows for the control checkpoint only."""
    res = evaluate(ckpts["control"], single_controlnet=ckpts["single"], windows=1, steps=2,
                   progress=False, body_constraints=False, guidance_variants=True)
    extra = [f"keypose + trajectory {k}" for k in GUIDANCE_VARIANTS]
    assert list(res) == [*ROW_NAMES[:4], *extra, *ROW_NAMES[4:6]]
    for name in extra:
        assert res[name]["seconds_per_clip"] > 0 and math.isfinite(res[name]["auj"])
    with pytest.raises(TypeError, match="guidance_variants"):
        evaluate(ckpts["control"], windows=1, steps=1, progress=False, guidance_variants="yes")


def _fast_cli(ckpts, out, *args):
    """The CLI on 2 windows, 2 steps, raw joints, no evaluator; rows.json into ``out``."""
    return main(["--control", str(ckpts["control"]), "--windows", "2", "--steps", "2",
                 "--no-progress", "--no-body-constraints", "--no-evaluator", *args,
                 "--out", str(out)])


def test_condition_scale_reaches_every_controlled_row_and_is_recorded(ckpts, tmp_path):
    """Eq. (14)'s w_c: 0 leaves only the text model (the conditions are ignored), so the
    controlled rows change; the text-only row does not; the CLI passes it and rows.json
    records it."""
    kw = dict(windows=2, steps=2, progress=False, body_constraints=False, evaluator=None)
    one = evaluate(ckpts["control"], **kw)
    out = tmp_path / "wc0"
    zero = _fast_cli(ckpts, out, "--condition-scale", "0")
    untimed = [k for k in one["text only"] if k != "seconds_per_clip"]
    assert [zero["text only"][k] for k in untimed] == [one["text only"][k] for k in untimed]
    for row in ("keypose + trajectory", "keypose + trajectory + guidance"):
        assert zero[row]["trajectory_error_3d"] != one[row]["trajectory_error_3d"], row
    assert json.loads((out / "rows.json").read_text())["config"]["condition_scale"] == 0.0
    for bad in (-1, float("nan"), True, "2"):
        with pytest.raises(ValueError, match="condition_scale"):
            evaluate(ckpts["control"], condition_scale=bad, **kw)
    with pytest.raises(ValueError, match="--condition-scale applies to the 3D table"):
        main(["--control", str(ckpts["control"]), "--no-3d", "--sketch",
              "--condition-scale", "1.5"])


def test_body_frequencies_reach_only_the_text_only_row_and_are_recorded(ckpts, tmp_path):
    """--body-frequencies (the legs and trunk of text-only clips): the text-only row changes,
    the controlled rows do not; rows.json records it; a bad value names the argument."""
    kw = dict(windows=2, steps=2, progress=False, body_constraints=False, evaluator=None)
    default = evaluate(ckpts["control"], **kw)
    out = tmp_path / "body1"
    one = _fast_cli(ckpts, out, "--body-frequencies", "1")
    assert one["text only"]["auj"] != default["text only"]["auj"]
    for row in ("keypose + trajectory", "keypose + trajectory + guidance"):
        assert one[row]["trajectory_error_3d"] == default[row]["trajectory_error_3d"], row
    assert json.loads((out / "rows.json").read_text())["config"]["body_frequencies"] == 1
    with pytest.raises(ValueError, match="body_frequencies must be None or an integer"):
        evaluate(ckpts["control"], body_frequencies=0, **kw)


def test_cli_writes_table_and_rows(ckpts, tmp_path, capsys):
    out = tmp_path / "eval"
    res = main(["--control", str(ckpts["control"]), "--windows", "3", "--steps", "1",
                "--out", str(out), "--no-progress", "--double-controlnet", str(ckpts["double"])])
    printed = capsys.readouterr().out
    assert BANDAI_NAMCO_ATTRIBUTION in printed and "| keypose + trajectory |" in printed
    assert "| double ControlNet |" in printed and "single ControlNet" not in printed
    assert (out / "table.md").read_text().startswith("| method |")
    saved = json.loads((out / "rows.json").read_text())
    assert saved["rows"] == res and saved["config"]["windows"] == 3
    assert saved["attribution"] == BANDAI_NAMCO_ATTRIBUTION
    assert not list(out.glob(".*"))                              # no temp files left


def test_missing_checkpoint(ckpts, tmp_path):
    with pytest.raises(FileNotFoundError, match="--control"):
        evaluate(tmp_path / "nope.pt", **FAST)
    with pytest.raises(FileNotFoundError, match="--single-controlnet"):
        evaluate(ckpts["control"], single_controlnet=tmp_path / "nope.pt", **FAST)
    with pytest.raises(FileNotFoundError, match="--stage control .*--double-controlnet"):
        evaluate(ckpts["control"], double_controlnet=tmp_path / "nope.pt", **FAST)
    from physlab._cli import guard
    assert guard("python -m physlab.motion.evaluate", main,
                 ["--control", str(tmp_path / "nope.pt"), "--no-progress"]) == 2


def test_base_checkpoint_is_not_an_ablation_checkpoint(ckpts):
    """A base is fine as --control (text-only rows, below), not as a ControlNet ablation."""
    with pytest.raises(ValueError, match="text-only"):
        evaluate(ckpts["control"], single_controlnet=ckpts["base"], **FAST)


@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_bad_window_count(ckpts, bad):
    with pytest.raises(ValueError, match="windows must be an integer >= 1"):
        evaluate(ckpts["control"], windows=bad, steps=2, progress=False)


def test_default_steps_are_generates():
    """Every evaluation samples with generate's default DDIM steps unless told otherwise."""
    import inspect

    from physlab.motion import evaluate as E
    from physlab.motion.sampling import DEFAULT_STEPS

    assert E._steps(None) == DEFAULT_STEPS and E._steps(7) == 7
    for fn in (E.evaluate, E.text_adherence, E.evaluate_sketch, E.evaluate_alignment_ablation):
        assert inspect.signature(fn).parameters["steps"].default is None, fn.__name__
    assert E._parser().parse_args(["--control", "x.pt"]).steps is None


def test_bad_steps_and_guidance(ckpts):
    with pytest.raises(ValueError, match="steps"):
        evaluate(ckpts["control"], windows=1, steps=0)
    with pytest.raises(ValueError, match="steps must be None"):
        evaluate(ckpts["control"], windows=1, steps=2.5)
    with pytest.raises(ValueError, match="guidance"):
        evaluate(ckpts["control"], windows=1, guidance=float("nan"))


def test_single_controlnet_flag_warns_for_a_plain_control_checkpoint(ckpts):
    with pytest.warns(UserWarning, match="is a ControlNet \\+ adapter checkpoint, not a "
                                         "single-ControlNet one"):
        evaluate(ckpts["control"], single_controlnet=ckpts["control"], windows=1, steps=1,
                 progress=False)
    with pytest.warns(UserWarning, match="single-ControlNet checkpoint, not a double-ControlNet"):
        evaluate(ckpts["control"], double_controlnet=ckpts["single"], windows=1, steps=1,
                 progress=False)
    with pytest.warns(UserWarning, match="--control .* is a double-ControlNet"):
        evaluate(ckpts["double"], windows=1, steps=1, progress=False)


def test_motion_statistics_analytic():
    """A body gliding forward at 1 m/s and drifting left, one wrist 0.3 m above the head."""
    from physlab.motion.evaluate import motion_statistics

    N, fps = 40, 20.0
    x = np.zeros((N, 22, 3))
    time_s = np.arange(N) / fps
    x[:, :, 2] = time_s[:, None] * 1.0                       # forward (+z), whole body
    x[:, :, 0] = time_s[:, None] * 0.5                       # left (+x)
    x[:, 15, 1] = 1.6                                        # head
    x[:, 20, 1] = 1.0
    x[:, 21, 1] = 1.0
    x[10, 21, 1] = 1.9                                       # right wrist up once
    s = motion_statistics(x, fps=fps)[0]
    wrist = 2 * 0.9 / (N - 1)                   # up and down once, relative to the pelvis
    np.testing.assert_allclose(s, [1.95, 0.975, np.hypot(1.0, 0.5), 0.3, wrist], atol=1e-12)
    with pytest.raises(ValueError, match="shape"):
        motion_statistics(np.zeros((40, 21, 3)))


def test_format_adherence_ratio_columns():
    """The speed and wrist-travel ratios come from the unrounded means (a 0.0224 against
    0.0726 m/s pelvis reads 0.02 / 0.07 in the rounded column, but +224 %)."""
    from physlab.motion.evaluate import STATISTICS, format_adherence

    def stats(speed, wrist):
        return dict(zip(STATISTICS, (0.0, 0.0, speed, 0.1, wrist)))

    res = {"per_content": {
               "wave": {"text": "a person waves the right hand", "n_real": 10,
                        "real": stats(0.0224, 0.043), "generated": stats(0.0726, 0.0215),
                        "recognised_as": ["wave", "bow"]},
               "bow": {"text": "a person bows", "n_real": 5, "real": stats(0.0, 0.0),
                       "generated": stats(0.1, 0.01), "recognised_as": ["bow"]}},
           "seeds": 2, "steps": 2, "guidance": 2.5, "accuracy": 0.67, "chance": 0.5}
    rows = {line.split(" | ")[0][2:]: line.split(" | ")
            for line in format_adherence(res).splitlines() if line.startswith("| a person")}
    assert rows["a person waves the right hand"][7:] == ["+224 %", "50 %", "1/2 |"]
    assert rows["a person bows"][7:9] == ["—", "—"]          # no real motion: no ratio


def test_text_adherence_structure_and_errors(ckpts, real_data):
    from physlab.motion.evaluate import format_adherence, text_adherence

    res = text_adherence(ckpts["control"], contents=("walk", "bow"), seeds=2, steps=2,
                         progress=False)
    assert set(res["per_content"]) == {"walk", "bow"} and res["chance"] == 0.5
    assert 0.0 <= res["accuracy"] <= 1.0
    walk = res["per_content"]["walk"]
    assert walk["text"] == "a person walks" and walk["n_real"] > 100
    assert walk["real"]["forward_m"] > 1.0 > abs(res["per_content"]["bow"]["real"]["forward_m"])
    assert len(walk["recognised_as"]) == 2
    assert "a person bows" in format_adherence(res)
    # jerk and skating: real windows of walks and bows against the 4 generated clips
    from physlab.motion.dataset import load_clips, make_windows
    from physlab.motion.metrics import jerk

    win = make_windows(load_clips(contents=["walk", "bow"]), length=40, stride=10)
    assert res["quality"]["real"]["auj"] == pytest.approx(jerk(win.joints)[0])
    assert set(res["quality"]["generated"]) == {"auj", "pj", "skating"}
    assert "Jerk (plain area" in format_adherence(res)
    # frequencies reach the sampler: with the DC term alone a clip stands still
    still = text_adherence(ckpts["control"], contents=("walk", "bow"), seeds=2, steps=2,
                           progress=False, frequencies=1)["per_content"]["walk"]["generated"]
    assert still["wrist_travel_m"] < 1e-6 < walk["generated"]["wrist_travel_m"], still
    with pytest.raises(ValueError, match="unknown"):
        text_adherence(ckpts["control"], contents=("fly",), progress=False)
    with pytest.raises(ValueError, match="seeds"):
        text_adherence(ckpts["control"], seeds=0, progress=False)


def test_sketch_evaluation_rows_and_cli(ckpts, tmp_path, capsys):
    """The 2D path: rows and columns, real clips at zero error, the guided sketch nearer its
    drawing than text only (even for the smoke model); with 2D encoders (stage align), a
    lifter and a direct-2D checkpoint every Table 1 row appears; the average protocol gives
    each window one joint; the CLI writes sketch_<protocol>.md."""
    from physlab.motion.baselines import MotionRetrieval, train_lifter
    from physlab.motion.evaluate import SKETCH_COLUMNS, evaluate_sketch, sketch_conditions

    rows = evaluate_sketch(ckpts["control"], windows=3, steps=2, progress=False)
    assert tuple(rows) == ("real clips", "text only", "3D generator, 2D guidance only",
                           "3D conditions, networks only", "3D conditions, networks + guidance")
    for r in rows.values():
        assert set(SKETCH_COLUMNS) <= set(r) and all(math.isfinite(r[k]) for k in SKETCH_COLUMNS)
    assert rows["real clips"]["trajectory_error_2d"] == 0 == rows["real clips"]["keypose_mpjpe_2d"]
    sk, text = rows["3D generator, 2D guidance only"], rows["text only"]
    assert sk["trajectory_error_2d"] < 0.5 * text["trajectory_error_2d"], rows

    d = tmp_path / "ck"
    align = train(stage="align", base_ckpt=str(ckpts["control"]), out=str(d / "align.pt"),
                  **SMOKE)["path"]
    direct = train(stage="control", base_ckpt=str(ckpts["base"]), direct_2d=True,
                   out=str(d / "direct.pt"), **SMOKE)["path"]
    lifter = train_lifter(d / "lifter.pt", steps=1, batch_size=4, max_clips=3,
                          progress=False)["path"]
    torch.set_num_threads(1)
    data = np.load(Path(__file__).resolve().parents[2] / "data" / "motion" /
                   "lesson_windows.npz")
    db = MotionRetrieval(data["real_walk"], ["a person walks"] * len(data["real_walk"]),
                         text_embed=lambda t: np.ones((len(t), 1)))
    rows = evaluate_sketch(align, windows=2, steps=1, progress=False, lifter=lifter,
                           direct_2d=direct, retrieval=db, guidance_only=True,
                           protocol="average")
    assert tuple(rows) == ("real clips", "text only", "retrieval", "lift-and-control",
                           "lift-and-control + guidance", "direct 2D", "direct 2D + guidance",
                           "physlab (2D encoders)", "physlab (2D encoders) + guidance",
                           "3D generator, 2D guidance only",
                           "3D conditions, networks only", "3D conditions, networks + guidance")
    assert all(math.isfinite(r["trajectory_error_2d"]) for r in rows.values())
    held = np.stack([np.load(Path(__file__).resolve().parents[2] / "data" / "motion" /
                             "lesson_windows.npz")["held_out"][0]] * 7)
    conds = sketch_conditions(held, "average")
    assert [int(c.mask.any(0).sum()) for c in conds] == [1] * 7
    assert [int(np.flatnonzero(c.mask.any(0))[0]) for c in conds] == [0, 1, 2, 3, 4, 5, 0]
    with pytest.raises(ValueError, match="protocol must be one of"):
        sketch_conditions(held, "mean")
    from physlab.motion.evaluate import evaluate_alignment_ablation

    ab = evaluate_alignment_ablation({"full": align, "again": align}, windows=2, steps=1,
                                     progress=False)
    assert tuple(ab) == ("full", "again")
    assert ab["full"]["trajectory_error_2d"] == ab["again"]["trajectory_error_2d"]  # same draws
    with pytest.raises(ValueError, match="has no 2D encoders"):
        evaluate_alignment_ablation({"plain": ckpts["control"]}, windows=2, steps=1,
                                    progress=False)
    out = tmp_path / "ev"
    main(["--control", str(ckpts["control"]), "--windows", "3", "--steps", "1", "--sketch",
          "--no-3d", "--no-evaluator", "--out", str(out), "--no-progress"])
    printed = capsys.readouterr().out
    assert "| 3D generator, 2D guidance only |" in printed and "| keypose + trajectory |" \
        not in printed
    assert (out / "sketch_cross.md").read_text().startswith("| method | traj. err.-2D")


def test_sketch_metrics_analytic():
    """A clip 0.1 m beside its drawn pelvis path in a front view: 2D error 0.1 scaled."""
    from physlab.motion.camera import Camera
    from physlab.motion.evaluate import sketch_metrics

    x = np.zeros((40, 22, 3))
    x[:, :, 2] = np.linspace(0, 2, 40)[:, None]
    x[:, 1:, 1] = 0.5
    cond = condition_from_window(x, t_r=10, keypose_at="first", joints=("pelvis",))
    moved = x + [0.1, 0.0, 0.0]
    r = sketch_metrics(moved[None], [cond], [Camera(scale=2.0)])
    assert r["trajectory_error_2d"] == pytest.approx(0.2)
    assert r["keypose_mpjpe_2d"] == pytest.approx(0.0, abs=1e-12)
    assert r["trajectory_error_3d"] == pytest.approx(0.1)


def test_blending_table_on_phase_change_windows(real_data):
    """Table A4 analogue on 8 held-out windows (no FID: fast): the real row is exact, the
    windows chosen are those that change most, the inversion blend is rigid and on the floor
    while the linear blend shrinks bones, and the table prints every row."""
    from physlab.motion.evaluate import (blending_windows, evaluate_blending,
                                         format_blending_table, phase_change_score)

    torch.set_num_threads(1)
    data = blending_windows(8, pool=64)
    assert data["joints"].shape == (8, 40, 22, 3) and len(data["text"]) == 8
    rest = phase_change_score(data["reference_joints"])
    assert data["score"].min() >= np.median(rest)                  # the top of the pool
    assert np.all(np.diff(data["score"]) <= 0)
    rows = evaluate_blending(windows=8, methods=("linear", "inversion"), evaluator=None,
                             progress=False)
    assert list(rows) == ["real", "linear", "inversion"]
    assert rows["real"]["MPJPE"] == 0.0 and rows["real"]["bones"] < 1e-3
    assert rows["inversion"]["bones"] < 1e-3 < rows["linear"]["bones"]
    assert rows["inversion"]["floor"] == 0.0
    assert rows["inversion"]["MPJPE"] < 0.3                        # no detour (G_m + pull)
    table = format_blending_table(rows)
    assert table.count("\n| ") == 5 and "| inversion |" in table       # header + 4 rows
    with pytest.raises(ValueError, match="methods must come from"):
        evaluate_blending(windows=8, methods=("morph",), evaluator=None, progress=False)


def test_blending_cli_uses_the_given_checkpoint_and_returns_the_rows(monkeypatch):
    """``--blending --control PATH`` blends with that generator (a missing file is an error
    naming --control) and ``main`` returns the table's rows."""
    import physlab.motion.evaluate as E

    with pytest.raises(FileNotFoundError, match="--control checkpoint runs/none.pt"):
        E.main(["--blending", "--control", "runs/none.pt", "--no-progress"])
    seen = {}

    def fake(**kw):
        seen.update(kw)
        return {"real": {"FID": 0.0, "AUJ": 1.0, "PJ": 0.1, "MPJPE": 0.0, "context": 0.0,
                         "step_ratio": 1.0, "bones": 0.0, "floor": 0.0, "seconds": 0.0}}
    monkeypatch.setattr(E, "evaluate_blending", fake)
    rows = E.main(["--blending", "--windows", "3", "--no-progress", "--no-evaluator"])
    assert seen["generator"] is None and seen["windows"] == 3 and list(rows) == ["real"]
    from physlab.motion.sampling import DEFAULT_CHECKPOINT

    E.main(["--blending", "--control", str(DEFAULT_CHECKPOINT), "--no-progress",
            "--no-evaluator"])
    assert seen["generator"].path == DEFAULT_CHECKPOINT and seen["generator"].has_control


def _yaw(points, degrees, about):
    """``points`` (..., 3) turned by ``degrees`` about the vertical through ``about`` (3,)."""
    th = np.radians(degrees)
    d = np.asarray(points, dtype=float) - about
    out = d.copy()
    out[..., 0] = d[..., 0] * np.cos(th) + d[..., 2] * np.sin(th)
    out[..., 2] = -d[..., 0] * np.sin(th) + d[..., 2] * np.cos(th)
    return out + about


def test_facing_is_the_canonicalisation_heading_for_any_leading_shape():
    from physlab.motion.evaluate import facing
    from physlab.motion.features import canonicalize, root_heading

    held = np.load(Path(__file__).resolve().parents[2] / "data" / "motion" /
                   "lesson_windows.npz")["held_out"][:3].astype(float)
    f = facing(held)
    assert f.shape == (3, 40)
    assert np.allclose(f[1], np.degrees(root_heading(held[1])))
    # a canonicalised window faces +z at frame 0
    assert facing(canonicalize(held[2])[0]) == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(ValueError, match=r"\(\.\.\., 22, 3\)"):
        facing(held[0, :, :21])


def test_pose_breakdown_separates_facing_from_posture_and_measures_the_turn():
    from physlab.motion.evaluate import POSE_GROUPS, facing, pose_breakdown
    from physlab.motion.skeleton import JOINT_NAMES

    assert sorted(j for g in POSE_GROUPS.values() for j in g) == sorted(JOINT_NAMES)
    held = np.load(Path(__file__).resolve().parents[2] / "data" / "motion" /
                   "lesson_windows.npz")["held_out"][:4].astype(float)
    # facing: turning a pose by +30° about the vertical adds 30° (the +z -> +x sense)
    turn = facing(_yaw(held[0, 5], 30.0, held[0, 5, 0])) - facing(held[0, 5])
    assert (turn + 180) % 360 - 180 == pytest.approx(30.0)
    conds = [condition_from_window(w, t_r=10, keypose_at=k)
             for w, k in zip(held, ("first", "last", "first", "last"))]
    exact = pose_breakdown(held, conds, held)
    assert exact["pose"] == 0 and exact["yaw_removed"] < 1e-12
    assert exact["turn_error"] < 1e-9 and exact["n_turn"] == 2
    assert clip_metrics(held, conds)["keypose_pose_3d"] == exact["pose"]
    # every key-frame pose turned by 20° about its pelvis: facing, not posture, is wrong
    turned = held.copy()
    for i, c in enumerate(conds):
        turned[i, c.key_frame] = _yaw(held[i, c.key_frame], 20.0, held[i, c.key_frame, 0])
    b = pose_breakdown(turned, conds, held)
    assert b["pose"] > 0.02 and b["yaw_removed"] < 1e-9
    assert b["pose"] == pytest.approx(clip_metrics(turned, conds)["keypose_pose_3d"])
    assert b["turn_error"] == pytest.approx(20.0)
    assert b["groups"]["pelvis"] < 1e-12 < b["groups"]["elbows, wrists"]
    assert b["clip_median"] <= b["clip_p90"] <= b["clip_max"]
    assert b["first"] > 0 and b["last"] > 0
    # a clip that never turns while its keypose does: slope 0, as far as asked: slope 1
    still = np.repeat(held[:, :1], held.shape[1], axis=1)
    asked = held.copy()
    for i in (1, 3):                                  # the last-frame keyposes: 80° and 120°
        for t in range(held.shape[1]):
            asked[i, t] = _yaw(held[i, 0], (60.0 + 20 * i) * t / (held.shape[1] - 1),
                               held[i, 0, 0])
    conds = [condition_from_window(w, t_r=10, keypose_at=k)
             for w, k in zip(asked, ("first", "last", "first", "last"))]
    assert pose_breakdown(asked, conds, asked)["turn_slope"] == pytest.approx(1.0)
    assert abs(pose_breakdown(still, conds, asked)["turn_slope"]) < 1e-9
    with pytest.raises(ValueError, match="one condition per clip"):
        pose_breakdown(held[:3], conds)


def test_evaluate_pose_detail_splits_text_only_and_networks_only_rows(ckpts, tmp_path, capsys):
    from physlab.motion.evaluate import format_pose_breakdown

    rows = evaluate(ckpts["control"], body_constraints=False, pose_detail=True,
                    evaluator=None, **FAST)
    with_detail = [k for k, r in rows.items() if "pose_breakdown" in r]
    assert with_detail == ["text only", "keypose + trajectory"]
    for k in with_detail:
        assert rows[k]["pose_breakdown"]["pose"] == pytest.approx(rows[k]["keypose_pose_3d"])
    table = format_pose_breakdown(rows)
    assert table.startswith("| method | pose err. (m)") and "| keypose + trajectory |" in table
    with pytest.raises(TypeError, match="pose_detail"):
        evaluate(ckpts["control"], pose_detail=1, evaluator=None, **FAST)
    out = tmp_path / "ev"
    main(["--control", str(ckpts["control"]), "--windows", "2", "--steps", "1",
          "--no-evaluator", "--pose-detail", "--out", str(out), "--no-progress"])
    assert "| method | pose err. (m)" in capsys.readouterr().out
    assert "turn slope" in (out / "table.md").read_text()
    with pytest.raises(ValueError, match="--pose-detail"):
        main(["--control", str(ckpts["control"]), "--no-3d", "--pose-detail"])


def test_evaluate_on_a_training_take_says_so(ckpts, capsys):
    train_rows = evaluate(ckpts["control"], takes=("001",), body_constraints=False,
                          evaluator=None, **FAST)
    held_rows = evaluate(ckpts["control"], body_constraints=False, evaluator=None, **FAST)
    assert train_rows["real clips"]["foot_skating"] != held_rows["real clips"]["foot_skating"]
    assert "windows of take 001 (not held out" in format_table(train_rows, ("001",))
    assert "held-out windows (take 002)" in format_table(held_rows)
    w = held_out_windows(2, takes="001")
    assert all(c.endswith("_001") for c in w["clip_id"])
    with pytest.raises(ValueError, match="no clips of take 999 .*takes there: 001, 002"):
        held_out_windows(2, takes=("999",))
    with pytest.raises(ValueError, match="takes must be"):
        held_out_windows(2, takes=())
    main(["--control", str(ckpts["control"]), "--windows", "2", "--steps", "1", "--take", "001",
          "--no-evaluator", "--no-progress"])
    assert "windows of take 001" in capsys.readouterr().out
    with pytest.raises(ValueError, match="--take"):
        main(["--control", str(ckpts["control"]), "--no-3d", "--take", "001"])


def test_follow_slope_is_one_for_a_copy_zero_for_a_constant_and_the_kept_share_between():
    """follow_slope (the --detail 'slope on real' row) is the least-squares slope, checked
    against numpy's polyfit and the analytic cases."""
    rng = np.random.default_rng(0)
    real = rng.normal(1.0, 0.5, 12)
    assert follow_slope(real, real + 3.0) == pytest.approx(1.0)            # copy plus offset
    assert follow_slope(real, np.full(12, 0.2)) == pytest.approx(0.0, abs=1e-12)
    assert follow_slope(real, 0.3 * real - 1.0) == pytest.approx(0.3)      # damped to 30 %
    got = rng.normal(size=12)
    assert follow_slope(real, got) == pytest.approx(np.polyfit(real, got, 1)[0])
    assert np.isnan(follow_slope(np.ones(5), np.arange(5.0)))              # real does not vary
    assert np.isnan(follow_slope([1.0], [2.0]))
    with pytest.raises(ValueError, match="real and got"):
        follow_slope(real, real[:5])


def test_a_base_checkpoint_gets_the_real_and_text_only_rows(ckpts, tmp_path):
    """`evaluate --control BASE` measures a text base on the same held-out windows (its text
    only equals the text only of a control model built on it); ablation rows need a control
    checkpoint."""
    kw = dict(windows=2, steps=2, progress=False, evaluator=None)
    rows = main(["--control", str(ckpts["base"]), "--windows", "2", "--steps", "2",
                 "--no-progress", "--no-evaluator", "--out", str(tmp_path)])
    assert list(rows) == ["real clips", "text only"]
    assert json.loads((tmp_path / "rows.json").read_text())["config"]["stage"] == "base"
    full = evaluate(ckpts["control"], **kw)
    untimed = [k for k in rows["text only"] if k != "seconds_per_clip"]
    assert [rows["text only"][k] for k in untimed] == [full["text only"][k] for k in untimed]
    with pytest.raises(ValueError, match="base .text-only. checkpoint"):
        evaluate(ckpts["base"], single_controlnet=ckpts["single"], **kw)
