"""Table 1's baselines: retrieval finds the window a sketch was drawn from (and only among the
asked action's windows), the lifter trains, resumes, lifts to the generator's 3D keywords,
and lift-and-control generates; bad input is named."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from physlab.motion.baselines import (MotionRetrieval, lift, lift_and_control, load_lifter,
                                      train_lifter)
from physlab.motion.camera import Camera, sketch_kwargs
from physlab.motion.dataset import condition_from_window

LESSON_WINDOWS = Path(__file__).resolve().parents[2] / "data" / "motion" / "lesson_windows.npz"


def _database():
    d = np.load(LESSON_WINDOWS)
    w = np.concatenate([d["real_walk"], d["held_out"]])
    texts = ["a person walks"] * len(d["real_walk"]) + [str(t) for t in d["held_out_text"]]
    return w, texts


def _embed(texts):
    """A fake text embedding: one axis per distinct text of the database (exact texts are
    nearest to themselves)."""
    _, vocab = _database()
    vocab = sorted(set(vocab))
    return np.stack([np.eye(len(vocab))[vocab.index(t)] if t in vocab else
                     np.ones(len(vocab)) / np.sqrt(len(vocab)) for t in texts])


@pytest.mark.parametrize("k", [3, 11, 20])
def test_retrieval_returns_the_window_the_sketch_was_drawn_from(k):
    w, texts = _database()
    db = MotionRetrieval(w, texts, text_embed=_embed)
    cam = Camera(1.0, 20, -30)
    cond = condition_from_window(w[k], t_r=25, keypose_at="first")
    kw = sketch_kwargs(cond, cam)
    out = db(texts[k], **kw)
    np.testing.assert_array_equal(out, w[k])
    assert set(np.array(texts)[db.candidates(texts[k])]) == {texts[k]}


def test_retrieval_bad_input():
    w, texts = _database()
    with pytest.raises(ValueError, match="texts for"):
        MotionRetrieval(w, texts[:-1])
    with pytest.raises(ValueError, match=r"shape \(M, N, 22, 3\)"):
        MotionRetrieval(w[0], texts)
    with pytest.raises(TypeError, match="camera must be"):
        MotionRetrieval(w, texts, text_embed=_embed)("a person walks", keypose_2d=np.zeros((22, 2)))


def test_lifter_trains_resumes_and_feeds_the_generator(real_data, tmp_path):
    out = tmp_path / "lifter.pt"
    res = train_lifter(out, steps=2, batch_size=8, max_clips=3, progress=False)
    assert res["step"] == 2 and np.isfinite(res["loss"])
    assert train_lifter(out, steps=3, batch_size=8, max_clips=3, progress=False)["step"] == 3
    lifter = load_lifter(out)
    cam = Camera(1.0, 15, 20)
    w, _ = _database()
    kw = sketch_kwargs(condition_from_window(w[0], t_r=12, keypose_at="last"), cam)
    k3, t3 = lift(lifter, **{k: v for k, v in kw.items()})
    assert k3.shape == (22, 3) and set(t3) == set(kw["trajectories_2d"])
    assert all(v.shape == (12, 3) for v in t3.values())
    x = lift_and_control("a person walks", lifter=lifter, steps=2, guidance_final=0, **kw)
    assert x.shape == (40, 22, 3) and np.all(np.isfinite(x))
    with pytest.raises(FileNotFoundError, match="train-lifter"):
        load_lifter(tmp_path / "none.pt")
