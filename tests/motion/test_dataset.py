"""Tests of physlab.motion.dataset: Bandai-Namco clips, windows, conditions, split.

Real clips: Bandai-Namco-Research-Motiondataset (CC BY-NC 4.0, © 2022 Bandai Namco Research
Inc.), read from the external data folder (``real_data`` fixture); only a few clips are
loaded, into a temporary cache.
"""
from pathlib import Path

import numpy as np
import pytest

from physlab.motion import dataset as D
from physlab.motion.dataset import (JOINT_COMBINATIONS, TRAJECTORY_JOINTS, MotionClip,
                                    action_text, condition_from_window, load_clips,
                                    make_windows, random_condition, split_by_take)
from physlab.motion.features import canonicalize, root_heading
from physlab.motion.skeleton import JOINT_NAMES

CLIPS = ["dataset-2_walk_normal_001", "dataset-1_bow_happy_001",
         "dataset-2_wave-right-hand_active_002"]


def _motion(T, seed=0):
    """A random walk of a random pose whose hips and shoulders face +z: (T, 22, 3)."""
    rng = np.random.default_rng(seed)
    pose = rng.uniform(-0.3, 0.3, (22, 3)) + np.array([0.0, 1.0, 0.0])
    pose[[1, 2, 16, 17]] = [[0.1, 0.9, 0.0], [-0.1, 0.9, 0.0], [0.2, 1.4, 0.0], [-0.2, 1.4, 0.0]]
    return pose + np.cumsum(rng.normal(0, 0.01, (T, 22, 3)), axis=0)


@pytest.fixture(scope="module")
def bandai_root(real_data):
    return real_data / "mocap" / "bandai_namco"


@pytest.fixture(scope="module")
def clips(bandai_root, tmp_path_factory):
    return load_clips(bandai_root, clip_ids=CLIPS, cache_dir=tmp_path_factory.mktemp("cache"))


# ----------------------------------------------------------------------------- text


def test_action_text():
    assert action_text("walk") == "a person walks"
    assert action_text("walk", "happy") == "a person walks happily"
    assert action_text("walk", "normal") == "a person walks"
    assert action_text("wave-right-hand", "chimpira") == "a person waves the right hand like a thug"
    with pytest.raises(ValueError, match="unknown content 'fly'"):
        action_text("fly")
    with pytest.raises(ValueError, match="unknown style 'sleepy'"):
        action_text("walk", "sleepy")


def _csv_rows(bandai_root):
    """labels.csv read with the csv module (independent of read_labels): list of dicts."""
    import csv

    with open(Path(bandai_root) / "labels.csv", newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_every_label_has_a_phrase(bandai_root):
    rows = D.read_labels(bandai_root)
    assert len(rows) == len(_csv_rows(bandai_root)) >= 314     # 874 since dataset-2 takes 003-010
    for r in rows:
        assert action_text(r["content"], r["style"]).startswith("a person ")


# ----------------------------------------------------------------------------- clips


def test_load_clips_real(clips, bandai_root, tmp_path_factory):
    assert [c.clip_id for c in clips] == sorted(CLIPS, key=[Path(r["file"]).stem for r in
                                                            D.read_labels(bandai_root)].index)
    frames = {Path(r["file"]).stem: int(r["frames"]) for r in D.read_labels(bandai_root)}
    for c in clips:
        assert c.fps == 20.0 and c.joints.shape == (c.n_frames, 22, 3)
        assert c.n_frames == int(np.floor((frames[c.clip_id] - 1) / 30 * 20 + 1e-6)) + 1
        assert c.joints[:, [7, 8, 10, 11], 1].min() == pytest.approx(0.0, abs=1e-9)
    wave = next(c for c in clips if c.content == "wave-right-hand")
    assert (wave.take, wave.style, wave.dataset) == ("002", "active", "dataset-2")
    assert wave.text == "a person waves the right hand energetically"


def test_load_clips_cache(bandai_root, tmp_path, monkeypatch):
    first = load_clips(bandai_root, clip_ids=CLIPS[:1], cache_dir=tmp_path)
    files = list((tmp_path / "bandai_namco_smpl22").glob("*.npz"))
    assert [f.name for f in files] == [f"{CLIPS[0]}_20fps_v1.npz"]
    # the second call reads the cache and never retargets
    monkeypatch.setattr(D, "retarget_to_smpl22", lambda *a, **k: pytest.fail("not cached"))
    again = load_clips(bandai_root, clip_ids=CLIPS[:1], cache_dir=tmp_path)
    np.testing.assert_array_equal(again[0].joints, first[0].joints)
    monkeypatch.undo()
    # a stale entry (other source size) is recomputed; cache_dir=False writes nothing
    np.savez(files[0], joints=np.zeros((2, 22, 3)), fps=20.0, source_bytes=1)
    np.testing.assert_allclose(load_clips(bandai_root, clip_ids=CLIPS[:1],
                                          cache_dir=tmp_path)[0].joints, first[0].joints)
    empty = tmp_path / "none"
    load_clips(bandai_root, clip_ids=CLIPS[:1], cache_dir=False)
    assert not empty.exists()
    # the default cache lives outside the repository
    monkeypatch.setenv("PHYSLAB_CACHE_DIR", str(tmp_path / "env"))
    assert D.default_cache_dir() == tmp_path / "env"
    monkeypatch.delenv("PHYSLAB_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert D.default_cache_dir() == tmp_path / "xdg" / "physlab"


def test_load_clips_errors(bandai_root, tmp_path, monkeypatch):
    with pytest.raises(ValueError, match=r"unknown contents \['fly'\]"):
        load_clips(bandai_root, contents=["walk", "fly"], cache_dir=False)
    with pytest.raises(ValueError, match="unknown clip ids"):
        load_clips(bandai_root, clip_ids=["dataset-1_walk_normal_999"], cache_dir=False)
    with pytest.raises(FileNotFoundError, match="no labels.csv"):
        load_clips(tmp_path, cache_dir=False)
    import physlab.datasets

    monkeypatch.setattr(physlab.datasets, "external_data_dir", lambda: None)
    with pytest.raises(FileNotFoundError, match="PHYSLAB_EXTERNAL_DATA"):
        load_clips(cache_dir=False)
    with pytest.raises(ValueError, match="fps"):
        load_clips(bandai_root, fps=0)


# ----------------------------------------------------------------------------- windows


def test_make_windows_synthetic():
    a, b, short = _motion(100, 0), _motion(57, 1), _motion(30, 2)
    w = make_windows([a, b, short], length=40, stride=10)
    # (100 - 40) // 10 + 1 = 7 and (57 - 40) // 10 + 1 = 2 windows; the short clip is dropped
    assert len(w) == 9 and w.joints.shape == (9, 40, 22, 3) and w.length == 40
    assert w.clip_id == ["clip0"] * 7 + ["clip1"] * 2
    np.testing.assert_array_equal(w.start, [0, 10, 20, 30, 40, 50, 60, 0, 10])
    for k in range(len(w)):
        src = (a if k < 7 else b)[w.start[k]:w.start[k] + 40]
        np.testing.assert_allclose(w.joints[k], canonicalize(src, ground=False), atol=1e-12)
        np.testing.assert_allclose(w.joints[k, 0, 0, [0, 2]], 0.0, atol=1e-12)
        assert root_heading(w.joints[k, :1])[0] == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError, match="window length 40 > clip clip1 length 30"):
        make_windows([a, short], drop_short=False)
    with pytest.raises(ValueError, match=r"every clip length \(longest 30 frames\)"):
        make_windows([short])
    with pytest.raises(ValueError, match="stride"):
        make_windows([a], stride=0)
    bad = a.copy()
    bad[5, 3, 1] = np.nan
    with pytest.raises(ValueError, match="clip clip0 contains NaN"):
        make_windows([bad])
    with pytest.raises(ValueError, match=r"shape \(T, 22, 3\)"):
        make_windows([a[:, :20]])


def test_make_windows_real(clips):
    w = make_windows(clips, length=40)
    assert w.fps == 20.0 and w.joints.shape[1:] == (40, 22, 3)        # 2 s at 20 fps
    counts = {c.clip_id: (c.n_frames - 40) // 10 + 1 for c in clips}
    assert len(w) == sum(counts.values())
    assert {t for t in w.text} == {"a person walks", "a person bows happily",
                                   "a person waves the right hand energetically"}
    assert set(w.content) == {"walk", "bow", "wave-right-hand"}
    assert np.all(np.isfinite(w.joints))


def test_mirror_windows_commutes_with_canonicalisation(clips):
    """Mirroring a canonical window must equal cutting the windows of the mirrored clip
    (reflected in the world, left / right swapped): canonicalisation commutes with the
    reflection, so mirrored windows are canonical training windows of a real motion."""
    w = make_windows(clips, length=40)
    m = D.mirror_windows(w)
    n = len(w)
    assert len(m) == 2 * n and m.fps == w.fps
    np.testing.assert_array_equal(m.joints[:n], w.joints)
    world = [MotionClip(clip_id=c.clip_id, dataset=c.dataset, content=c.content, style=c.style,
                        take=c.take, joints=D.mirror_joints(c.joints), fps=c.fps)
             for c in clips]
    np.testing.assert_allclose(m.joints[n:], make_windows(world, length=40).joints, atol=1e-9)
    np.testing.assert_allclose(m.joints[n:, 0, 0, [0, 2]], 0.0, atol=1e-12)
    assert np.abs(root_heading(m.joints[n:, :1].reshape(-1, 22, 3))).max() < 1e-9
    assert m.text[n:] == [D.mirror_text(t) for t in w.text]
    assert "a person waves the left hand energetically" in m.text[n:]
    assert set(m.content[n:]) == {"walk", "bow", "wave-left-hand"}
    assert m.clip_id[n] == w.clip_id[0] + "/mirror" and m.style == w.style * 2
    with pytest.raises(TypeError, match="windows must be a Windows"):
        D.mirror_windows(w.joints)


# ----------------------------------------------------------------------------- conditions


@pytest.mark.parametrize("at", ["first", "last"])
def test_condition_fill_rule(at):
    window = canonicalize(_motion(40, 4))
    cond = condition_from_window(window, t_r=12, keypose_at=at)
    key = 0 if at == "first" else 39
    rows = np.arange(12) if at == "first" else np.arange(28, 40)
    assert cond.key_frame == key and cond.t_r == 12 and cond.joints == TRAJECTORY_JOINTS
    np.testing.assert_array_equal(cond.keypose, window[key])
    assert cond.trajectory.shape == (40, 6, 3) and cond.mask.shape == (40, 6)
    np.testing.assert_array_equal(np.flatnonzero(cond.mask.any(axis=1)), rows)
    assert cond.mask[rows].all()
    np.testing.assert_array_equal(cond.trajectory[rows], window[rows][:, list(TRAJECTORY_JOINTS)])
    assert not cond.trajectory[~cond.mask].any()
    K = cond.keypose_dense
    assert K.shape == (40, 22, 3) and np.array_equal(K[key], window[key])
    assert not np.delete(K, key, axis=0).any()
    assert [JOINT_NAMES[j] for j in TRAJECTORY_JOINTS] == [
        "pelvis", "left_foot", "right_foot", "head", "left_wrist", "right_wrist"]


def test_condition_joint_subsets_and_defaults():
    window = _motion(40, 5)
    cond = condition_from_window(window, t_r=5, joints=["right_wrist", "pelvis"])
    assert cond.joints == (0, 21)
    np.testing.assert_array_equal(np.flatnonzero(cond.mask.any(axis=0)), [0, 5])
    assert condition_from_window(window, joints=15).mask[:, 3].all()     # t_r = N by default
    assert len(JOINT_COMBINATIONS) == 63 and len(set(JOINT_COMBINATIONS)) == 63
    c1 = random_condition(window, np.random.default_rng(7))
    c2 = random_condition(window, np.random.default_rng(7))
    assert c1.joints == c2.joints and c1.t_r == c2.t_r and c1.key_frame == c2.key_frame
    assert 5 <= c1.t_r <= 40 and c1.mask.sum() == c1.t_r * len(c1.joints)


def test_random_condition_single_joint_share():
    """single_joint = p adds single-joint strokes: their share is 6/63 + p (1 - 6/63); p = 0
    draws exactly what it drew before the option existed (same random stream)."""
    window = _motion(40, 5)
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    for _ in range(20):
        a, b = random_condition(window, rng_a), random_condition(window, rng_b, single_joint=0.0)
        assert a.joints == b.joints and a.t_r == b.t_r and a.key_frame == b.key_frame
    rng = np.random.default_rng(0)
    n = 4000
    singles = np.mean([len(random_condition(window, rng, single_joint=0.5).joints) == 1
                       for _ in range(n)])
    expected = 6 / 63 + 0.5 * (1 - 6 / 63)
    assert abs(singles - expected) < 4 * np.sqrt(expected * (1 - expected) / n)
    assert all(len(random_condition(window, rng, single_joint=1.0).joints) == 1
               for _ in range(50))
    with pytest.raises(ValueError, match="single_joint"):
        random_condition(window, rng, single_joint=1.5)


@pytest.mark.parametrize("kwargs, message", [
    (dict(t_r=0), r"t_r must be an integer in 1..40"),
    (dict(t_r=41), r"t_r must be an integer in 1..40"),
    (dict(t_r=2.5), r"t_r must be an integer"),
    (dict(keypose_at="middle"), "'first' or 'last'"),
    (dict(joints=["tail"]), "unknown joint 'tail'"),
    (dict(joints=["left_knee"]), "joint 'left_knee' has no trajectory condition"),
    (dict(joints=[]), "joints is empty"),
])
def test_condition_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        condition_from_window(_motion(40), **kwargs)


def test_condition_rejects_bad_windows():
    with pytest.raises(ValueError, match=r"window must have shape \(T, 22, 3\)"):
        condition_from_window(np.zeros((40, 22, 2)))
    w = _motion(40)
    w[3, 20] = np.nan
    with pytest.raises(ValueError, match="window contains NaN .* frame 3, joint left_wrist"):
        condition_from_window(w)


def test_condition_from_real_window(clips):
    w = make_windows([c for c in clips if c.content == "walk"], length=40)
    cond = condition_from_window(w.joints[0], t_r=20, keypose_at="last",
                                 joints=("pelvis", "left_foot"))
    assert cond.mask.sum() == 40 and cond.mask[20:, :2].all()
    # the pelvis walks about 1.1 m/s * 1 s along +z over the last 20 frames
    pelvis = cond.trajectory[20:, 0]
    assert 0.7 < pelvis[-1, 2] - pelvis[0, 2] < 1.6


# ----------------------------------------------------------------------------- split


def _label_clips(bandai_root):
    """Every clip of labels.csv as a MotionClip with dummy joints (no BVH parsing)."""
    return [MotionClip(clip_id=Path(r["file"]).stem, dataset=r["dataset"], content=r["content"],
                       style=r["style"], take=r["take"], joints=np.zeros((1, 22, 3)))
            for r in D.read_labels(bandai_root)]


def test_split_by_take_holds_out_whole_clips(bandai_root):
    every = _label_clips(bandai_root)
    rows = _csv_rows(bandai_root)
    n_test = sum(r["take"] == "002" for r in rows)
    train, test = split_by_take(every)
    assert (len(train), len(test)) == (len(rows) - n_test, n_test) and n_test >= 88
    ids_train, ids_test = {c.clip_id for c in train}, {c.clip_id for c in test}
    assert not ids_train & ids_test and len(ids_train | ids_test) == len(rows)
    assert {c.take for c in test} == {"002"}
    assert {c.take for c in train} == {r["take"] for r in rows} - {"002"}
    # every held-out clip has its (dataset, content, style) in training
    seen = {(c.dataset, c.content, c.style) for c in train}
    assert all((c.dataset, c.content, c.style) in seen for c in test)
    with pytest.raises(ValueError, match=r"no clip has take \['099'\]"):
        split_by_take(every, test_takes="099")


def test_split_windows_never_straddle(clips):
    train, test = split_by_take(clips)
    wtr, wte = make_windows(train), make_windows(test)
    assert not set(wtr.clip_id) & set(wte.clip_id)
    assert set(wte.clip_id) == {"dataset-2_wave-right-hand_active_002"}


def test_turn_windows_turn_the_body_and_its_path_progressively(clips):
    from physlab.motion.evaluate import facing

    w = make_windows(clips, length=40)
    t = D.turn_windows(w, max_degrees=90.0, seed=3)
    n = len(w)
    assert len(t) == 2 * n and t.text == list(w.text) * 2
    assert t.clip_id[n].endswith("/turned")
    np.testing.assert_array_equal(t.joints[:n], w.joints)
    c = t.joints[n:]
    np.testing.assert_allclose(c[:, 0], w.joints[:, 0], atol=1e-12)        # frame 0 kept
    np.testing.assert_allclose(c[..., 1], w.joints[..., 1])                # heights kept
    np.testing.assert_allclose(np.linalg.norm(np.diff(c[:, :, 0, [0, 2]], axis=1), axis=-1),
                               np.linalg.norm(np.diff(w.joints[:, :, 0, [0, 2]], axis=1),
                                              axis=-1), atol=1e-12)        # step lengths kept
    # each frame's pose is the original turned about its pelvis: same limb lengths, and the
    # facing turns by a linear ramp to θ, the same θ per window (mod 360)
    np.testing.assert_allclose(np.linalg.norm(c - c[:, :, :1], axis=-1),
                               np.linalg.norm(w.joints - w.joints[:, :, :1], axis=-1),
                               atol=1e-12)
    extra = (facing(c) - facing(w.joints) + 180) % 360 - 180                # (n, 40) degrees
    theta = extra[:, -1]
    assert np.all(np.abs(theta) <= 90) and np.ptp(theta) > 30
    np.testing.assert_allclose(extra, theta[:, None] * np.linspace(0, 1, 40)[None], atol=1e-8)
    # the path turns with the body: a step's direction turns by the frame's angle
    d0 = np.diff(w.joints[:, :, 0, [0, 2]], axis=1)
    d1 = np.diff(c[:, :, 0, [0, 2]], axis=1)
    ang = np.degrees(np.arctan2(d0[..., 0], d0[..., 1]) - np.arctan2(d1[..., 0], d1[..., 1]))
    moving = np.linalg.norm(d0, axis=-1) > 1e-3
    np.testing.assert_allclose(((ang + extra[:, 1:] + 180) % 360 - 180)[moving], 0, atol=1e-6)
    # a toe swings round the pelvis by at most the frame's turn times its distance from the
    # pelvis, on top of its own turned step: a few mm per frame, so the copies hardly skate
    # more than the originals (docs/motion_experiments.md, "Where the pose error sits")
    from physlab.motion.metrics import foot_skating_ratio

    dth = np.radians(np.abs(theta)) / 39                                    # (n,) rad / frame
    toe = lambda x: x[:, :, [10, 11]][..., [0, 2]]                          # noqa: E731
    own = np.linalg.norm(np.diff(toe(w.joints), axis=1), axis=-1)
    got = np.linalg.norm(np.diff(toe(c), axis=1), axis=-1)
    reach = np.linalg.norm(toe(w.joints) - w.joints[:, :, None, 0][..., [0, 2]], axis=-1)
    assert np.all(got <= own + dth[:, None, None] * reach[:, :-1] + 1e-9)
    assert np.all(got >= own - dth[:, None, None] * reach[:, :-1] - 1e-9)
    sk = [foot_skating_ratio(x, fps=w.fps).mean() for x in (w.joints, c)]
    assert abs(sk[1] - sk[0]) < 0.01, sk
    with pytest.raises(ValueError, match="max_degrees"):
        D.turn_windows(w, max_degrees=0)
    with pytest.raises(TypeError, match="Windows"):
        D.turn_windows(w.joints)
