"""Tests of physlab.motion.evaluator: the metrics against analytic cases (FID of Gaussians,
diversity of known sets, R-precision of perfect and random embeddings), the InfoNCE loss,
features and mirroring, bad input, smoke training and resuming, safe loading, and the shipped
evaluator on held-out Bandai-Namco windows."""
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy import linalg

from physlab.motion.checkpoint import CHECKPOINT_KIND, CHECKPOINT_VERSION, save_checkpoint
from physlab.motion.evaluator import (
    DEFAULT_EVALUATOR,
    MIRROR_PERMUTATION,
    STAGE,
    TextMotionEvaluator,
    diversity,
    euclidean_distance_matrix,
    evaluate_embeddings,
    fid,
    held_out_data,
    info_nce,
    mirror_joints,
    mirror_text,
    mm_dist,
    motion_features,
    r_precision,
    r_precision_chance,
    train,
)
from physlab.motion.skeleton import JOINT_NAMES

# constant learning rate, so that a run cut in two equals one run
SMOKE = {"smoke": True, "progress": False, "lr": 1e-3, "min_lr": 1e-3}


def _gaussian_sample(mu, S, n, seed):
    """``n`` points whose sample mean is exactly ``mu`` and sample covariance (ddof 1)
    exactly ``S``: whitened noise, coloured by the Cholesky factor of ``S``."""
    Z = np.random.default_rng(seed).standard_normal((n, len(mu)))
    Z -= Z.mean(0)
    Z = Z @ np.linalg.inv(np.linalg.cholesky(np.cov(Z, rowvar=False))).T     # cov(Z) = I
    return mu + Z @ np.linalg.cholesky(S).T


def _spd(d, seed):
    A = np.random.default_rng(seed).standard_normal((d, d))
    return A @ A.T / d + 0.1 * np.eye(d)


# ----------------------------------------------------------------------------- FID


def test_fid_of_identical_sets_is_zero():
    X = np.random.default_rng(0).standard_normal((300, 16))
    assert fid(X, X) == pytest.approx(0.0, abs=1e-8)


def test_fid_of_diagonal_gaussians_is_the_closed_form():
    """FID = |μ1 − μ2|² + Σ_k (√a_k − √b_k)² for Σ1 = diag(a), Σ2 = diag(b)."""
    a, b = np.array([1.0, 4.0, 0.25]), np.array([9.0, 1.0, 0.25])
    mu1, mu2 = np.array([0.0, 1.0, 2.0]), np.array([3.0, -1.0, 2.0])
    X = _gaussian_sample(mu1, np.diag(a), 500, 1)
    Y = _gaussian_sample(mu2, np.diag(b), 400, 2)
    expect = np.sum((mu1 - mu2) ** 2) + np.sum((np.sqrt(a) - np.sqrt(b)) ** 2)
    assert expect == pytest.approx(13.0 + 4.0 + 1.0)
    assert fid(X, Y) == pytest.approx(expect, rel=1e-9)


def test_fid_of_general_gaussians_matches_the_sqrtm_formula():
    """Non-commuting covariances: the reference formula with scipy.linalg.sqrtm(Σ1 Σ2)."""
    d = 6
    S1, S2 = _spd(d, 3), _spd(d, 4)
    mu1, mu2 = np.zeros(d), np.linspace(-1, 1, d)
    X, Y = _gaussian_sample(mu1, S1, 200, 5), _gaussian_sample(mu2, S2, 150, 6)
    expect = (np.sum((mu1 - mu2) ** 2) + np.trace(S1) + np.trace(S2)
              - 2 * np.trace(linalg.sqrtm(S1 @ S2)).real)
    assert fid(X, Y) == pytest.approx(expect, rel=1e-8)
    assert fid(Y, X) == pytest.approx(expect, rel=1e-8)                  # symmetric
    shift = np.arange(d, dtype=float)
    assert fid(X + shift, Y + shift) == pytest.approx(expect, rel=1e-8)  # translation invariant


def test_fid_with_fewer_samples_than_dimensions_stays_real_and_nonnegative():
    rng = np.random.default_rng(7)
    X, Y = rng.standard_normal((20, 64)), rng.standard_normal((20, 64))
    v = fid(X, Y)
    assert np.isfinite(v) and v > 0
    assert fid(X, X + 0.5) == pytest.approx(64 * 0.25, rel=1e-6)            # mean shift only


# ----------------------------------------------------------------------------- others


def test_diversity_of_known_sets():
    line = np.array([[0.0], [1.0], [2.0], [3.0]])
    assert diversity(line, n_pairs=None) == pytest.approx(10 / 6)         # mean |i - j|
    same = np.ones((400, 5))
    assert diversity(same, n_pairs=300) == 0.0
    X = np.random.default_rng(0).standard_normal((2000, 8))
    assert diversity(X, 300, seed=1) == pytest.approx(diversity(X[:300], None), rel=0.08)
    assert diversity(X, 300, seed=1) == diversity(X, 300, seed=1)          # seeded


def test_r_precision_is_one_for_perfectly_matched_embeddings():
    E = np.random.default_rng(0).standard_normal((96, 16))
    np.testing.assert_array_equal(r_precision(E, E, top_k=3, batch=32), [1, 1, 1])


def test_r_precision_of_random_embeddings_is_chance():
    rng = np.random.default_rng(1)
    T, M = rng.standard_normal((32 * 300, 16)), rng.standard_normal((32 * 300, 16))
    rp = r_precision(T, M, top_k=3, batch=32)
    np.testing.assert_allclose(rp, np.array([1, 2, 3]) / 32, atol=0.012)
    np.testing.assert_allclose(r_precision_chance(len(T), 3, 32), np.array([1, 2, 3]) / 32)


def test_r_precision_merges_duplicate_texts():
    """A batch of one repeated text has one candidate: every motion hits, chance is 1. With
    two texts the motion of each is nearest its own text's embedding."""
    rng = np.random.default_rng(2)
    t = rng.standard_normal((1, 8)).repeat(32, 0)
    m = rng.standard_normal((32, 8))
    texts = ["a person walks"] * 32
    np.testing.assert_array_equal(r_precision(t, m, 1, 32, texts=texts), [1.0])
    np.testing.assert_array_equal(r_precision_chance(32, 1, 32, texts=texts), [1.0])
    # two texts, each motion = its text + small noise; the other text is far
    a, b = np.zeros(8), np.full(8, 5.0)
    labels = ["a"] * 16 + ["b"] * 16
    T = np.array([a if s == "a" else b for s in labels])
    M = T + 0.01 * rng.standard_normal(T.shape)
    assert r_precision(T, M, 1, 32, texts=labels)[0] == 1.0
    np.testing.assert_allclose(r_precision_chance(32, 2, 32, texts=labels), [0.5, 1.0])


def test_mm_dist_and_distance_matrix():
    t = np.zeros((2, 3))
    m = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    assert mm_dist(t, m) == pytest.approx(3.0)                              # (5 + 1) / 2
    A, B = np.random.default_rng(3).standard_normal((2, 5, 4))
    brute = np.linalg.norm(A[:, None] - B[None], axis=-1)
    np.testing.assert_allclose(euclidean_distance_matrix(A, B), brute, atol=1e-12)


def test_evaluate_embeddings_of_a_real_set_against_itself():
    rng = np.random.default_rng(4)
    T = rng.standard_normal((64, 8))
    r = evaluate_embeddings(T, T, T, texts=[f"t{i}" for i in range(64)])
    assert r["fid"] == pytest.approx(0, abs=1e-8) and r["mm_dist"] == 0
    assert r["r_precision_top3"] == 1.0 and r["n"] == 64
    assert r["r_precision_chance_top3"] == pytest.approx(3 / 32)
    assert r["diversity"] == pytest.approx(diversity(T, None))


def test_info_nce():
    tau = 0.5
    m = torch.eye(2)
    # distinct texts, orthonormal matched pairs: log(1 + exp(-1/τ)) in both directions
    loss = info_nce(m, m, torch.tensor([0, 1]), tau)
    assert loss.item() == pytest.approx(np.log1p(np.exp(-1 / tau)), rel=1e-5)
    # the same text: the other pair is not a negative, nothing to push apart
    assert info_nce(m, m, torch.tensor([0, 0]), tau).item() == pytest.approx(0.0, abs=1e-7)
    # a mismatch costs more than a match
    assert info_nce(m, m.flip(0), torch.tensor([0, 1]), tau) > loss


# ----------------------------------------------------------------------------- features


def _window(seed=0, T=40):
    rng = np.random.default_rng(seed)
    x = 0.3 * rng.standard_normal((1, T, 22, 3))
    return x + np.linspace(0, 1, T)[None, :, None, None] * np.array([0.0, 0.0, 1.0])


def test_motion_features_shapes_and_invariants():
    x = _window()
    f = motion_features(x)
    assert f.shape == (1, 40, 69) and f.dtype == torch.float32
    torch.testing.assert_close(f[0, :, :3], torch.as_tensor(x[0, :, 0], dtype=torch.float32))
    assert torch.all(f[:, 0, 3:6] == 0)                                     # no velocity at 0
    torch.testing.assert_close(f[0, :, 6:9], torch.as_tensor(x[0, :, 1] - x[0, :, 0],
                                                             dtype=torch.float32))
    # moving the window moves only the pelvis position channels
    g = motion_features(x + np.array([0.5, 0.0, -2.0]))
    torch.testing.assert_close(g[..., 3:], f[..., 3:], atol=1e-5, rtol=0)


def test_mirroring_joints_and_texts():
    x = _window(1)
    np.testing.assert_array_equal(mirror_joints(mirror_joints(x)), x)
    y = mirror_joints(x)
    lw, rw = JOINT_NAMES.index("left_wrist"), JOINT_NAMES.index("right_wrist")
    np.testing.assert_array_equal(y[..., rw, 0], -x[..., lw, 0])
    np.testing.assert_array_equal(y[..., rw, 1:], x[..., lw, 1:])
    assert sorted(MIRROR_PERMUTATION) == list(range(22))
    torch.testing.assert_close(mirror_joints(torch.as_tensor(x)), torch.as_tensor(y))
    assert mirror_text("a person waves the left hand") == "a person waves the right hand"
    assert mirror_text("a person walks to the right") == "a person walks to the left"
    assert mirror_text("a person bows sadly") == "a person bows sadly"
    assert mirror_text("a person walks and turns left") == "a person walks and turns right"


# ----------------------------------------------------------------------------- bad input


def test_bad_metric_input_is_named():
    X = np.zeros((10, 4))
    with pytest.raises(ValueError, match="real_emb has 1 row"):
        fid(X[:1], X)
    with pytest.raises(ValueError, match="gen_emb contains NaN"):
        fid(X, np.full((3, 4), np.nan))
    with pytest.raises(ValueError, match="same width"):
        fid(X, np.zeros((5, 3)))
    with pytest.raises(ValueError, match="only 10 pairs"):
        r_precision(X, X, batch=32)
    with pytest.raises(ValueError, match="same shape"):
        mm_dist(X, X[:5])
    with pytest.raises(ValueError, match="n_pairs=None"):
        diversity(X, n_pairs=300)
    with pytest.raises(ValueError, match="texts has 3 entries"):
        r_precision(X, X, batch=5, texts=["a", "b", "c"])


# ----------------------------------------------------------------------------- training


@pytest.fixture(scope="module")
def smoke_run(real_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("evaluator") / "smoke.pt"
    res = train(out=str(out), export=str(out.with_name("smoke16.pt")), **SMOKE)
    return res


def test_smoke_training_writes_a_loadable_evaluator(smoke_run):
    assert smoke_run["step"] == 4 and np.isfinite(smoke_run["loss"])
    ev = TextMotionEvaluator.from_checkpoint(smoke_run["export"])
    assert ev.train_takes and "002" not in ev.train_takes
    data = held_out_data()
    m = ev.encode_motion(data["joints"][:5])
    t = ev.encode_text(data["text"][:3] + ["a person does a cartwheel"])    # unknown: hashed
    assert m.shape == (5, ev.embed_dim) and t.shape == (4, ev.embed_dim)
    np.testing.assert_allclose(np.linalg.norm(m, axis=1), 1, atol=1e-5)
    r = ev.evaluate(data["joints"][:40], data["joints"][40:80], data["text"][40:80])
    assert set(r) >= {"fid", "r_precision_top3", "mm_dist", "diversity"}
    with pytest.raises(ValueError, match="joints contains NaN"):
        ev.encode_motion(np.full((2, 40, 22, 3), np.nan))
    with pytest.raises(ValueError, match=r"joints must have shape \(N, T, 22, 3\)"):
        ev.encode_motion(np.zeros((40, 22, 3)))
    with pytest.raises(ValueError, match="20 frames per window"):
        ev.encode_motion(np.zeros((2, 20, 22, 3)))
    with pytest.raises(ValueError, match="one str per window of gen_joints"):
        ev.evaluate(data["joints"][:4], data["joints"][:4], ["a person walks"])


def test_resumed_training_equals_one_run(real_data, tmp_path):
    one = train(out=str(tmp_path / "one.pt"), steps=4, **SMOKE)
    train(out=str(tmp_path / "two.pt"), steps=2, **SMOKE)
    two = train(out=str(tmp_path / "two.pt"), steps=4, **SMOKE)               # resumes
    assert one["step"] == two["step"] == 4 and two["trained"] == 2
    again = train(out=str(tmp_path / "two.pt"), steps=4, **SMOKE)             # nothing left
    assert again["trained"] == 0 and again["loss"] == two["loss"]             # not NaN
    a = torch.load(one["path"], weights_only=True)["model"]
    b = torch.load(two["path"], weights_only=True)["model"]
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=0, atol=0)


class _Payload:
    """Unpickling this calls ``open(marker, "w")``: a file appears if the pickle is run."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


@pytest.mark.parametrize("entry", ["from_checkpoint", "train --resume"])
def test_a_malicious_pickle_is_refused_not_run(tmp_path, entry):
    marker, path = tmp_path / "PWNED", tmp_path / "evil.pt"
    torch.save({"kind": CHECKPOINT_KIND, "version": CHECKPOINT_VERSION, "stage": STAGE,
                "model": {"w": torch.zeros(2)}, "x": _Payload(marker)}, path)
    calls = {"from_checkpoint": lambda: TextMotionEvaluator.from_checkpoint(path),
             "train --resume": lambda: train(out=str(path), resume=True, data_root=str(tmp_path),
                                             **SMOKE)}
    with pytest.raises(ValueError, match=r"evil\.pt was refused: it holds Python objects"):
        calls[entry]()
    assert not marker.exists(), f"{entry} executed the pickle payload"


def test_wrong_or_missing_checkpoints_get_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="physlab.motion.evaluator train"):
        TextMotionEvaluator.from_checkpoint(tmp_path / "none.pt")
    gen = save_checkpoint(tmp_path / "gen.pt", {"kind": CHECKPOINT_KIND,
                                                "version": CHECKPOINT_VERSION, "stage": "control",
                                                "model": {"w": torch.zeros(1)}})
    with pytest.raises(ValueError, match="'control' checkpoint of the motion generator"):
        TextMotionEvaluator.from_checkpoint(gen)


# ----------------------------------------------------------------------------- shipped


@pytest.fixture(scope="module")
def shipped():
    torch.set_num_threads(1)
    return TextMotionEvaluator.from_checkpoint(DEFAULT_EVALUATOR)


@pytest.fixture(scope="module")
def held_out(real_data):
    """All held-out (take 002) windows."""
    return held_out_data()


def _evenly_spaced(data, n=64):
    """``n`` evenly spaced held-out windows, as physlab.motion.evaluate picks them."""
    idx = np.round(np.linspace(0, len(data["joints"]) - 1, n)).astype(int)
    return data["joints"][idx], [data["text"][i] for i in idx]


def test_shipped_evaluator_is_small_safe_and_documented(shipped):
    assert DEFAULT_EVALUATOR.stat().st_size <= 10 * 2**20
    torch.load(DEFAULT_EVALUATOR, weights_only=True)
    readme = (Path(DEFAULT_EVALUATOR).parent / "EVALUATOR.md").read_text()
    assert "CC BY-NC 4.0" in readme and "Apache" in readme
    assert "002" not in shipped.train_takes and "001" in shipped.train_takes


def test_shipped_evaluator_scores_training_texts_without_the_encoder(shipped):
    from physlab.motion.text import training_vocabulary

    assert set(training_vocabulary(styles=True)) <= set(shipped.text_cache.texts)
    shipped.encode_text(training_vocabulary(styles=True)[:50])
    assert shipped.text_cache.n_encoded == 0 and shipped.text_cache.encoder is None


def test_shipped_evaluator_tells_real_from_broken_motion(held_out, shipped):
    """Held-out windows split in two halves (the first and the second half of every clip's
    windows): FID real vs real is far below real vs noised (5 cm) or frozen (frame 0 held)
    windows. Measured 2026-11-25 (338 / 379 windows): 0.008, noised 0.56,
    frozen 0.22."""
    X, clip = held_out["joints"], np.asarray(held_out["clip_id"])
    first = np.zeros(len(X), dtype=bool)
    for c in set(clip):
        w = np.flatnonzero(clip == c)
        first[w[:len(w) // 2]] = True
    A, B = shipped.encode_motion(X[first]), X[~first]
    rng = np.random.default_rng(0)
    real = fid(A, shipped.encode_motion(B))
    noised = fid(A, shipped.encode_motion(B + 0.05 * rng.standard_normal(B.shape)))
    frozen = fid(A, shipped.encode_motion(np.repeat(B[:, :1], B.shape[1], axis=1)))
    assert real < 0.05
    assert noised > 10 * real and frozen > 10 * real


def test_shipped_evaluator_ranks_held_out_texts_well_above_chance(held_out, shipped):
    """R-precision of 64 held-out windows with their own texts. Measured 2026-11-25: top-1
    0.97, top-3 1.00 (chance 0.036 / 0.107); shuffled texts: top-3 0.06, MM-Dist 1.39 (0.37)."""
    X, texts = _evenly_spaced(held_out)
    r = shipped.evaluate(X, X, texts)
    assert r["r_precision_top3"] >= 0.8 >= 3 * r["r_precision_chance_top3"]
    assert r["r_precision_top1"] >= 0.5 >= 3 * r["r_precision_chance_top1"]
    shuffled = [texts[i] for i in np.random.default_rng(0).permutation(len(texts))]
    s = shipped.evaluate(X, X, shuffled)
    assert s["mm_dist"] > r["mm_dist"] + 0.3
    assert s["r_precision_top3"] < 2 * s["r_precision_chance_top3"]
