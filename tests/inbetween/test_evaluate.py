"""Ground-truth evaluation and the real-drawing check (physlab.inbetween.evaluate)."""
import json

import imageio.v3 as iio
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
    # no occlusions: nothing inpainted, texture quality q = 1 in every frame (Sec. 5.2)
    assert all(r["q_fwd_min"] == r["q_bwd_min"] == 1.0 for r in rows
               if r["method"] in ("physlab", "physlab_diagonal"))


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


def test_cli_texture_quality_flag_is_checked(capsys):
    with pytest.raises(SystemExit):
        evaluate.main(["--texture-quality", "iou"])
    assert "--texture-quality: invalid choice: 'iou'" in capsys.readouterr().err


def test_real_animated_drawing_no_flips(real_data):
    r = evaluate.animated_drawing_inbetween("char2", n_frames=5)
    assert r["flipped"] == 0
    assert r["max_handle_error_px"] < 1.5
    res = r["result"]
    assert res.frames.shape[0] == 5 and res.frames.shape[-1] == 4
    # the keys are the drawing posed at the two BVH frames, and the poses differ
    assert np.abs(r["skeletons"][0].xy - r["skeletons"][-1].xy).max() > 20


# ----------------------------------------------------------------------------- opaque keys
@pytest.fixture(scope="module")
def far_pair():
    pairs = inbetween_benchmark(size=96)
    return next(p for p in pairs if p.kind == "far")


def test_run_methods_on_opaque_rgb_keys(far_pair):
    """Regression: RGB keys crashed with "could not broadcast (H,W,3) into (H,W,4)"; now every
    method returns 3-channel frames over the same paper, keys exact at both ends."""
    from physlab.image import over_white, to_uint8

    key0, key1 = (to_uint8(over_white(k)) for k in far_pair.keyframes())  # RGB on white
    frames, res, sec = evaluate.run_methods(key0, key1, far_pair.skeleton0, far_pair.skeleton1,
                                            5, animation=far_pair.animation(5))
    assert set(frames) == set(evaluate.METHODS) == set(sec)
    for m, f in frames.items():
        assert f.shape == (5, 96, 96, 3) and f.dtype == np.float32, m
        np.testing.assert_allclose(f[0], key0 / 255, atol=1e-6)
        np.testing.assert_allclose(f[-1], key1 / 255, atol=1e-6)
    # cross-dissolve of opaque keys: the mean of the keys at t = 0.5 (analytic)
    np.testing.assert_allclose(frames["cross_dissolve"][2], (key0 / 255 + key1 / 255) / 2,
                               atol=1e-5)
    truth = np.stack([to_uint8(over_white(g)) for g in far_pair.ground_truth(np.linspace(0, 1, 5))])
    scores = {m: evaluate.score_frames(frames[m], truth) for m in evaluate.METHODS}
    assert all(np.isfinite(v) for s in scores.values() for v in s.values())
    assert scores["physlab"]["psnr_mid"] > scores["cross_dissolve"]["psnr_mid"] + 3
    # an opaque RGBA key (alpha 255 everywhere) gives the same frames as its RGB
    rgba = [np.dstack([k, np.full(k.shape[:2], 255, np.uint8)]) for k in (key0, key1)]
    again, _, _ = evaluate.run_methods(*rgba, far_pair.skeleton0, far_pair.skeleton1, 5,
                                       animation=far_pair.animation(5))
    for m in evaluate.METHODS:
        np.testing.assert_array_equal(again[m], frames[m])


# ----------------------------------------------------------------------------- one's own pair
def test_evaluate_folder_end_to_end(tmp_path, capsys):
    """`--pairs DIR` on RGB keys on white with two ground truths: the table of every method
    at t = 0.25, 0.5 and their mean, the contact sheet, rows.json."""
    from _drawings import write_pair

    write_pair(tmp_path / "mine", gt=(0.25, 0.5), opaque=True)
    out = tmp_path / "out"
    assert evaluate.main(["--pairs", str(tmp_path / "mine"), "--frames", "5", "--no-progress",
                          "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "5 frames (keys included), 96x96 px" in text
    for group in ("t=0.25", "t=0.5", "mean"):
        assert all(f"{group} | {m} |" in text for m in evaluate.METHODS), text
    rows = json.loads((out / "rows.json").read_text())
    assert len(rows) == 2 * len(evaluate.METHODS) and {r["t"] for r in rows} == {0.25, 0.5}
    score = {(r["t"], r["method"]): r for r in rows}
    assert score[0.5, "physlab"]["psnr"] > score[0.5, "cross_dissolve"]["psnr"] + 3
    assert score[0.5, "physlab"]["cd"] < score[0.5, "cross_dissolve"]["cd"]
    assert (out / "table.md").read_text().startswith("group | method | n | psnr | ssim | cd")
    sheet = iio.imread(out / "contact.png")
    assert sheet.shape[0] > 300 and sheet.shape[1] > 300  # 5 rows x 5 columns of panels


def test_evaluate_folder_without_ground_truth_writes_the_sheet(tmp_path):
    from _drawings import write_pair

    write_pair(tmp_path / "p", gt=(), animation=4)
    r = evaluate.evaluate_folder(tmp_path / "p", out=tmp_path / "o")
    assert r["n_frames"] == 4 and r["table"] == "" and r["rows"] == []
    assert [f.name for f in r["files"]] == ["contact.png"]
    assert all(f.shape == (4, 96, 96, 4) for f in r["frames"].values())  # RGBA keys: RGBA


def test_evaluate_folder_passes_occlusions_to_the_pipeline(tmp_path, capsys):
    """A pair whose forearm folds across the body, with the keys' true occlusion regions in
    occlusions<k>.json: the pipeline builds layered templates and flags no overlap."""
    from _drawings import write_pair

    from physlab.inbetween import LayeredTemplate, occlusion_benchmark

    pair = occlusion_benchmark(96)[0]
    write_pair(tmp_path / "occ", pair=pair, occlusions=True)
    assert evaluate.main(["--pairs", str(tmp_path / "occ"), "--frames", "5", "--no-progress"]) == 0
    text = capsys.readouterr().out
    n0, n1 = (len(o) for o in pair.occlusions())
    assert f"occlusion regions: key0 {n0}, key1 {n1} (layered templates)" in text
    assert "t=0.5 | physlab |" in text and "overlap" not in text
    assert (tmp_path / "occ" / "evaluation" / "contact.png").is_file()  # default --out
    r = evaluate.evaluate_folder(tmp_path / "occ", n_frames=3)
    assert all(isinstance(t, LayeredTemplate) for t in r["result"].templates)
    assert not any(r["result"].flags)


@pytest.mark.parametrize("spoil, match", [
    (lambda d: (d / "key0.png").unlink(), r"missing key0\.png"),
    (lambda d: (d / "skeleton1.json").write_text('{"names": [], "xy": []}'),
     r"skeleton1\.json: missing field\(s\) \['parents'\]"),
    (lambda d: iio.imwrite(d / "gt_0.5.png", np.zeros((50, 96, 3), np.uint8)),
     r"gt_0\.5\.png is 96x50 px but the keys are 96x96"),
], ids=["no key0", "skeleton fields", "gt size"])
def test_physlab_evaluate_pairs_bad_folder_is_one_line(tmp_path, capsys, spoil, match):
    import re

    from _drawings import write_pair

    from physlab import cli

    write_pair(tmp_path / "p", gt=(0.5,))
    spoil(tmp_path / "p")
    status = cli.main(["evaluate", "inbetween", "--pairs", str(tmp_path / "p"), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith("physlab: error: "), err
    assert re.search(match, err[0]), err[0]
    assert not (tmp_path / "p" / "evaluation").exists()


# ------------------------------------------------------------------ skeleton interpolation
def test_interpolation_errors_on_the_procedural_benchmark():
    """Its truth is the local-angle blend: that method is exact, positions are not."""
    pairs = evaluate.interpolation_pairs(("procedural",), size=128, n_frames=5)
    assert len(pairs) == 14 and all(len(p.truth) == 5 for p in pairs)
    rows = evaluate.interpolation_errors(pairs, methods=("local_angles", "positions"))
    err = {(r["pair"], r["method"]): r for r in rows}
    assert all(err[p.name, "local_angles"]["all_worst"] < 1e-9 for p in pairs)
    swing = err["arm_swing", "positions"]   # the 115° arm swing: the chord cuts the arc
    assert swing["mid_worst"] > 5 and swing["mid_mean"] <= swing["mid_worst"]
    table = evaluate.interpolation_table(rows)
    assert table.count("\n") == 1 + 2 and "*0.00*" in table


def test_interpolation_psnr_true_animation_equals_its_method():
    pair = evaluate.interpolation_pairs(("procedural",), size=128, n_frames=5)[0]
    rows = evaluate.interpolation_psnr([pair], methods=("local_angles",), progress=False)
    psnr = {r["method"]: r["psnr"] for r in rows}
    assert set(psnr) == {"local_angles", *evaluate.INTERPOLATION_REFERENCES}
    assert psnr["local_angles"] == psnr["true_animation"] > psnr["cross_dissolve"]
    table = evaluate.interpolation_table([], rows)
    assert "true_animation" in table and "(1)" in table


def test_interpolation_pairs_from_real_motion(real_data):
    pairs = evaluate.interpolation_pairs(("mocap", "animated_drawings"), size=128, n_frames=5)
    for src in ("mocap", "animated_drawings"):
        mine = [p for p in pairs if p.source == src]
        assert len(mine) > 50
        shown = [p for p in mine if p.images is not None]
        assert 1 <= len(shown) <= (len(evaluate.MOCAP_CLIPS) if src == "mocap"
                                   else len(evaluate.AD_SHOTS))
    # the true middle pose is not the local-angle blend of the keys
    rows = evaluate.interpolation_errors(pairs[:20], methods=("local_angles",))
    assert np.mean([r["mid_worst"] for r in rows]) > 1.0
    # an AnimatedDrawings shot renders keys and the true middle drawing at one size
    ad = next(p for p in pairs if p.source == "animated_drawings" and p.images is not None)
    k0, k1, mid = ad.images()
    assert k0.shape == k1.shape == mid.shape and max(k0.shape[:2]) == 128


@pytest.mark.parametrize("kwargs, match", [
    (dict(sources=("cartoons",)), "unknown interpolation source"),
    (dict(n_frames=6), "odd"),
    (dict(gap=0.0), "gap"),
])
def test_interpolation_pairs_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        evaluate.interpolation_pairs(**kwargs)


def test_cli_interpolation_table(tmp_path, capsys):
    assert evaluate.main(["--interpolation", "--no-psnr", "--size", "128", "--frames", "5",
                          "--no-progress", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "procedural | local_angles | 14" in out and "mid worst px" in out
    rows = json.loads((tmp_path / "interpolation_rows.json").read_text())
    assert rows["psnr"] == [] and {r["method"] for r in rows["errors"]} == \
        set(evaluate.INTERPOLATION_METHODS)


# ------------------------------------------------- real drawings with a limb over the body
def test_limb_body_overlaps_tiny_case():
    """A hand swung across the trunk overlaps it; the same bones apart in the rest pose
    count, bones already touching at rest do not; the deepest overlap is 2r − distance."""
    from physlab.inbetween import Skeleton

    names = ["root", "hip", "torso", "left_shoulder", "left_elbow", "left_hand"]
    parents = np.array([-1, 0, 1, 2, 3, 4])
    rest = Skeleton(names, parents, np.array([[50, 80], [50, 78], [50, 40], [60, 40],
                                              [80, 40], [100, 40]], float))
    # the forearm folded back across the torso bone, crossing it (distance 0)
    posed = rest.with_xy(np.array([[50, 80], [50, 78], [50, 40], [60, 40], [60, 60],
                                   [40, 60]], float))
    ov = evaluate.limb_body_overlaps(posed, rest, radius=3.0)
    assert ov[0] == ("left_hand", "torso", pytest.approx(6.0))
    assert evaluate.limb_body_overlaps(rest, rest, radius=3.0) == []
    assert evaluate.limb_body_overlaps(posed, posed, radius=3.0) == []   # already in the drawing


@pytest.mark.parametrize("call, match", [
    (lambda: evaluate.scan_occluded_shots(characters=["char9"]), "characters must be"),
    (lambda: evaluate.scan_occluded_shots(motions=[]), "motions is empty"),
    (lambda: evaluate.scan_occluded_shots(size=32), "size must be"),
    (lambda: evaluate.scan_occluded_shots(span=0), "span must be"),
    (lambda: evaluate.OccludedDrawingPair("x", "char9", "dab", 0, 1), "character must be"),
    (lambda: evaluate.OccludedDrawingPair("x", "char1", "salsa", 0, 1), "motion must be"),
    (lambda: evaluate.OccludedDrawingPair("x", "char1", "dab", 0, 1, size=10), "size must be"),
    (lambda: evaluate.occluded_drawing_pairs({}), "shots must be"),
    (lambda: evaluate.OccludedDrawingPair("x", "char1", "dab", 0, 1, t_junctions="y"),
     "t_junctions must be True or False"),
    (lambda: evaluate.OccludedDrawingPair("x", "char1", "dab", 0, 1, truth="mesh"),
     "truth must be one of"),
    (lambda: evaluate.occluded_drawing_pairs(truth=None), "truth must be one of"),
    (lambda: evaluate.evaluate_occluded_drawings(truth="part"), "truth must be one of"),
])
def test_occluded_drawings_bad_arguments(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_limb_body_overlaps_bad_arguments():
    from physlab.inbetween import character_skeleton

    sk = character_skeleton(128)
    with pytest.raises(ValueError, match="radius must be"):
        evaluate.limb_body_overlaps(sk, sk, radius=-1.0)
    with pytest.raises(TypeError, match="skeleton and rest must be"):
        evaluate.limb_body_overlaps(sk, None, 3.0)


def test_occluded_drawings_skip_without_data(monkeypatch, capsys):
    from physlab import datasets

    monkeypatch.setattr(datasets, "external_data_dir", lambda: None)
    r = evaluate.evaluate_occluded_drawings()
    assert r["skipped"] and "external data" in r["skipped"] and r["rows"] == []
    assert evaluate.main(["--occluded", "--source", "animated_drawings", "--no-progress"]) == 0
    assert "skipped AnimatedDrawings occlusions" in capsys.readouterr().out


def test_source_needs_occluded():
    with pytest.raises(ValueError, match="--source animated_drawings is for --occluded"):
        evaluate.main(["--source", "animated_drawings", "--skip-benchmark"])
    with pytest.raises(ValueError, match="--truth parts is for --occluded --source"):
        evaluate.main(["--occluded", "--truth", "parts", "--skip-benchmark"])
    with pytest.raises(SystemExit):   # argparse: "argument --truth: invalid choice"
        evaluate.main(["--occluded", "--source", "animated_drawings", "--truth", "mesh"])


def test_scan_finds_shots_whose_key_overlaps(real_data):
    found = evaluate.scan_occluded_shots(["char2"], ["dab"], size=128)
    assert found, "the dab motion folds char2's arm across its chest"
    for r in found:
        assert r["overlap_px"] > 0 and r["overlaps"][0][2] == r["overlap_px"]
    # the shots of the table really have a limb over the body at exactly one key
    for name, shot in evaluate.AD_OCCLUDED_SHOTS.items():
        p = evaluate.OccludedDrawingPair(name, *shot, size=128)
        ov = [evaluate.limb_body_overlaps(s, p.rest, p.radius) for s in (p.skeleton0,
                                                                          p.skeleton1)]
        assert sum(bool(o) for o in ov) == 1, name
        assert max(o[0][2] for o in ov if o) > 0
        assert p.skeleton0.depth is not None


@pytest.mark.parametrize("truth", evaluate.OCCLUDED_TRUTHS)
def test_occluded_drawing_route_small(real_data, tmp_path, truth):
    # (its speed is benchmarks/bench_inbetween.py --occluded's business, not a test's)
    shot = {"char4_dab": evaluate.AD_OCCLUDED_SHOTS["char4_dab"]}
    r = evaluate.evaluate_occluded_drawings(shot, size=96, n_frames=3, out=tmp_path,
                                            progress=False, max_iter=300, truth=truth)
    assert {row["truth"] for row in r["rows"]} == {truth}
    methods = {row["method"] for row in r["rows"]}
    assert methods == set(evaluate.METHODS) | {evaluate.SINGLE_SHEET}
    for row in r["rows"]:
        for m in evaluate.METRICS:
            assert np.isfinite(row[f"{m}_mid"]) and np.isfinite(row[f"{m}_all"])
        if row["method"].startswith("physlab"):
            assert np.isfinite(row["handle_error_px"]) and row["flipped"] >= 0
    assert r["rows"][0]["regions0"] + r["rows"][0]["regions1"] >= 1  # suggested regions
    assert "layered" in r["physlab"] and "one sheet" in r["physlab"]
    assert (tmp_path / "pairs" / "char4_dab.png").is_file() and (tmp_path / "table.md").is_file()
    assert (tmp_path / "contact.png").is_file() and tmp_path / "contact.png" in r["files"]


def test_occluded_drawing_regions_carry_suggested_t_junctions(real_data):
    from physlab.inbetween.occlusion import T_JUNCTION_TOLERANCE

    shot = evaluate.AD_OCCLUDED_SHOTS["char4_dab"]
    p = evaluate.OccludedDrawingPair("char4_dab", *shot, size=128)
    regs = [o for key in p.occlusions() for o in key]
    assert regs
    for o in regs:
        tj = o.t_junctions
        assert len(tj) >= 2 and len(tj) % 2 == 0, o.label
        # on the region's outline (within the template's tolerance)
        from scipy import ndimage
        edge = o.mask & ~ndimage.binary_erosion(o.mask)
        yx = np.argwhere(edge)
        d = np.linalg.norm(tj[:, None] - yx[None, :, ::-1], axis=2).min(axis=1)
        assert d.max() <= T_JUNCTION_TOLERANCE
    off = evaluate.OccludedDrawingPair("char4_dab", *shot, size=128, t_junctions=False)
    assert all(len(o.t_junctions) == 0 for key in off.occlusions() for o in key)
    # capsules as wide as the limbs in the rest drawing (char2: a dress and arms of some width)
    shot2 = evaluate.AD_OCCLUDED_SHOTS["char2_dab"]
    thin, wide = (evaluate.OccludedDrawingPair("char2_dab", *shot2, size=192, rest_widths=w)
                  for w in (False, True))
    assert thin.widths is None and wide.widths["torso"] > wide.widths["left_hand"] > 1.0
    a = [sum(o.mask.sum() for o in key) for key in thin.occlusions()]
    b = [sum(o.mask.sum() for o in key) for key in wide.occlusions()]
    assert a != b and sum(b) > 0
    with pytest.raises(ValueError, match="rest_widths"):
        evaluate.OccludedDrawingPair("char2_dab", *shot2, size=192, rest_widths="yes")


# ------------------------------------------ the second ground truth: the drawing cut into parts
@pytest.fixture(scope="module")
def parts_pair(real_data):
    """char1 at the zombie shot's keys: both arms swing forward across the chest at key 1."""
    shot = evaluate.AD_OCCLUDED_SHOTS["char1_zombie"]
    return evaluate.OccludedDrawingPair("char1_zombie", *shot, size=128, truth="parts")


def _rest_drawing(p):
    """The rest drawing as the parts truth draws it: straight RGBA, alpha × foreground."""
    from physlab.inbetween.template import as_rgba_float

    ref = as_rgba_float(p.image).copy()
    ref[..., 3] *= p.mask
    return ref


def test_parts_truth_at_rest_is_the_drawing(parts_pair):
    """Every part at its rest place: the drawing comes back to float precision (the joint
    caps lie under identical pixels), and the truth at the keys is a different image from the
    one-sheet truth's (the two models disagree once the arms move)."""
    from physlab.inbetween.cutout import render_cutout

    p = parts_pair
    ref = _rest_drawing(p)
    for rest in (p.rest, p.rest.with_depth(p.skeleton0.depth)):
        out = render_cutout(p.image, p.parts, p.rest, rest)
        assert np.abs(out[..., 3] - ref[..., 3]).max() < 1e-6
        assert np.abs((out - ref)[..., :3] * ref[..., 3:]).max() < 1e-6
    assert set(p.parts.names) >= {"torso", "head", "left_upper_arm", "left_forearm",
                                  "right_thigh", "right_shin"}
    sheet = evaluate.OccludedDrawingPair("char1_zombie", *evaluate.AD_OCCLUDED_SHOTS[
        "char1_zombie"], size=128)
    a, b = p.ground_truth(1.0), sheet.ground_truth(1.0)
    assert a.shape == b.shape and np.abs(a - b).mean() > 0.01


def test_parts_truth_moves_every_part_rigidly(parts_pair):
    """Each part's warped layer has the rest part's area, its centroid moved by the part's
    transform and its second moments rotated by it (distances within the part preserved);
    the transforms are rotations that take the part's bones onto the posed bones."""
    from physlab.inbetween.cutout import cutout_layers, part_transforms

    p = parts_pair
    sk = p.skeleton1
    T = part_transforms(p.parts, p.rest, sk)
    ref = _rest_drawing(p)
    H, W = ref.shape[:2]
    yy, xx = np.mgrid[:H, :W]

    def moments(a):
        m = a.sum()
        c = np.array([(a * xx).sum(), (a * yy).sum()]) / m
        d = np.stack([xx - c[0], yy - c[1]], -1)
        return m, c, np.einsum("hw,hwi,hwj->ij", a, d, d) / m

    layers = {n: layer for n, kind, _, layer in cutout_layers(p.image, p.parts, p.rest, sk)
              if kind == "part"}
    assert set(layers) == set(p.parts.names)
    for k, name in enumerate(p.parts.names):
        R, t = T[k, :, :2], T[k, :, 2]
        assert np.allclose(R.T @ R, np.eye(2), atol=1e-12) and np.linalg.det(R) > 0
        js = p.parts.bones[k]
        if name != "torso":   # a limb's bone lands exactly on the posed bone
            for j in (js[0], p.rest.parents[js[0]]):
                assert np.allclose(R @ p.rest.xy[j] + t, sk.xy[j], atol=1e-6), name
        m0, c0, C0 = moments(ref[..., 3] * p.parts.drawn(k))
        m1, c1, C1 = moments(layers[name][..., 3])
        assert abs(m1 / m0 - 1) < 0.02, name
        assert np.linalg.norm(c1 - (R @ c0 + t)) < 0.1, name
        assert np.abs(C1 - R @ C0 @ R.T).max() < 0.02 * np.abs(C0).max() + 0.05, name


def test_parts_truth_paints_the_nearer_part(parts_pair):
    """At key 1 the forearms lie across the chest, nearer than the torso (BVH depths). The
    layers are painted far to near; wherever two or more parts cover a pixel fully (and
    nothing lies partly over the nearest of them) the nearest part's colour shows — there
    the forearms over the torso; with the depths negated the torso over the forearms."""
    from physlab.inbetween.cutout import cutout_layers, render_cutout

    p = parts_pair
    sk = p.skeleton1
    tops = []
    for s in (sk, sk.with_depth(-sk.depth)):
        layers = cutout_layers(p.image, p.parts, p.rest, s)
        out = render_cutout(p.image, p.parts, p.rest, s)
        depth = [d for *_, d, _ in layers]
        assert all(a >= b for a, b in zip(depth, depth[1:]))        # far to near
        alpha = np.stack([lay[..., 3] for *_, lay in layers])     # (L, H, W)
        is_part = np.array([kind == "part" for _, kind, _, _ in layers])
        opaque = alpha > 0.999
        L = len(layers)
        top = L - 1 - np.argmax(opaque[::-1], axis=0)               # nearest opaque layer
        above = (alpha > 0) & (np.arange(L)[:, None, None] > top)
        ok = (opaque & is_part[:, None, None]).sum(0) >= 2
        ok &= ~above.any(0) & opaque.any(0) & is_part[top]
        want = np.take_along_axis(np.stack([lay for *_, lay in layers]),
                                  top[None, ..., None], 0)[0]
        assert ok.sum() > 100
        assert np.abs(out[ok][:, :3] - want[ok][:, :3]).max() < 2e-3  # alpha ≥ 0.999
        names = np.array([n for n, *_ in layers])[top]
        torso = opaque[[i for i, (n, k, *_) in enumerate(layers) if n == "torso" and
                        k == "part"][0]]
        tops.append((names, ok & torso))
    (n0, ok0), (n1, ok1) = tops
    crossed = ok0 & ok1 & np.char.endswith(n0, "_forearm")
    assert crossed.sum() > 20                     # forearms in front of the chest ...
    # ... behind it with the depths negated (the head, then nearer still, over a few)
    assert not np.char.endswith(n1[crossed], "_forearm").any()
    assert (n1[crossed] == "torso").mean() > 0.8


def test_parts_truth_joint_caps_only_fill_gaps(parts_pair):
    """The joint caps change the truth only where a cap lies (they fill the wedges that open
    outside bent elbows and knees) and add coverage there."""
    from physlab.inbetween.cutout import cutout_layers, render_cutout, segment_parts

    p = parts_pair
    sk = p.skeleton_at(0.5)[0]
    bare = segment_parts(p.mask, p.rest, caps=False)
    a = render_cutout(p.image, p.parts, p.rest, sk)
    b = render_cutout(p.image, bare, p.rest, sk)
    cap = np.zeros(a.shape[:2], bool)
    for _, kind, _, layer in cutout_layers(p.image, p.parts, p.rest, sk):
        if kind == "cap":
            cap |= layer[..., 3] > 0
    assert np.abs(a - b)[~cap].max() < 1e-5
    filled = (a[..., 3] > 0.5) & (b[..., 3] < 0.5)
    assert filled.sum() > 0 and not (filled & ~cap).any()
