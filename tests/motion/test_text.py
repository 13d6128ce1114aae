"""Tests of physlab.motion.text: the action-word encoder (all-MiniLM-L6-v2 standing in for
Sketch2Anim's CLIP text encoder), its weights check, the embedding cache and neighbours.

The real model is loaded once per module (``encoder`` fixture, ~0.2 s: physlab's own forward
pass, tests/motion/test_minilm.py checks it against sentence-transformers); everything about the cache's logic uses a tiny
bag-of-words encoder (the seam) instead.
"""
import json
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from physlab.motion import text as T
from physlab.motion.dataset import ACTION_PHRASES, STYLE_PHRASES, action_text
from physlab.motion.text import (EMBED_DIM, WEIGHTS_SHA256, ActionEncoder, EmbeddingCache,
                                 WeightsChecksumError, action_prompt, cosine_similarity,
                                 default_model_dir, demo_vocabulary, file_sha256, nearest,
                                 training_vocabulary, verify_weights)


class BagOfWords:
    """Test double for the encoder seam: text -> (1, #walks, #runs, #waves, #bows)."""

    name = "bag-of-words"
    WORDS = ("walks", "runs", "waves", "bows")

    def __init__(self):
        self.calls = []

    def __call__(self, texts):
        self.calls.append(list(texts))
        return np.array([[1.0] + [t.split().count(w) for w in self.WORDS] for t in texts])


@pytest.fixture(scope="module")
def encoder():
    # one torch thread: a few short texts gain nothing from more, and stay fast when other
    # processes compete for the cores
    return ActionEncoder(num_threads=1).load()


@pytest.fixture(scope="module")
def vocab_cache(encoder):
    """The 24 Bandai-Namco texts, 3 x 20 styled ones and the generic demo actions, encoded
    by the real model (the full styled vocabulary, 432 texts, takes ~1 s more)."""
    styled = [action_text(c, s) for c in ("walk", "bow", "wave-right-hand")
              for s in STYLE_PHRASES]
    return EmbeddingCache.build(demo_vocabulary() + styled, encoder)


# ----------------------------------------------------------------------------- weights


def test_file_sha256_of_a_tiny_file(tmp_path):
    p = tmp_path / "abc.bin"
    p.write_bytes(b"abc")                              # FIPS 180-2 test vector
    assert file_sha256(p) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    assert file_sha256(p, chunk_size=1) == file_sha256(p)


def test_installed_weights_pass_the_check():
    path = verify_weights()
    assert path == default_model_dir() / "model.safetensors"
    assert file_sha256(path) == WEIGHTS_SHA256 == (
        "53aa51172d142c89d9012cce15ae4d6cc0ca6895895114379cacb4fab128d9db")


@pytest.fixture
def corrupt_model_dir(tmp_path):
    """A copy of the installed model folder with one byte of the weights flipped."""
    dst = shutil.copytree(default_model_dir(), tmp_path / "model")
    weights = dst / "model.safetensors"
    with open(weights, "r+b") as f:
        f.seek(weights.stat().st_size // 2)           # inside the tensor data
        b = f.read(1)
        f.seek(-1, 1)
        f.write(bytes([b[0] ^ 0xFF]))
    return dst


def test_corrupted_copy_is_refused(corrupt_model_dir):
    with pytest.raises(WeightsChecksumError, match="corrupt.*force-reinstall"):
        verify_weights(corrupt_model_dir)
    enc = ActionEncoder(model_dir=corrupt_model_dir)
    with pytest.raises(WeightsChecksumError):
        enc.encode(["a person walks"])
    assert not enc.loaded


def test_constructor_checks_its_arguments():
    with pytest.raises(ValueError, match="batch_size"):
        ActionEncoder(batch_size=0)
    with pytest.raises(ValueError, match="num_threads"):
        ActionEncoder(num_threads=0)


def test_wrong_expected_hash_and_missing_weights(tmp_path):
    with pytest.raises(WeightsChecksumError, match="expected 0000"):
        ActionEncoder(expected_sha256="0" * 64).load()
    with pytest.raises(ValueError, match="64 hex digits"):
        verify_weights(expected_sha256="not-a-hash")
    with pytest.raises(FileNotFoundError, match="missing.*reinstall"):
        ActionEncoder(model_dir=tmp_path).load()


# ----------------------------------------------------------------------------- encoder


def test_embeddings_shape_unit_norm_deterministic(encoder):
    texts = ["a person walks", "a person bows", "a person waves the right hand happily"]
    E = encoder.encode(texts)
    assert E.shape == (3, EMBED_DIM) and E.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(E, axis=1), 1.0, atol=1e-6)
    assert np.array_equal(E, encoder.encode(texts))                  # same call, same bits
    import torch

    threads = torch.get_num_threads()
    encoder.encode(texts)
    assert torch.get_num_threads() == threads                          # restored
    # batch composition changes only the padding: same vectors to float32 round-off
    single = np.concatenate([encoder.encode(t) for t in texts])
    np.testing.assert_allclose(single, E, atol=1e-6)
    assert encoder.encode([]).shape == (0, EMBED_DIM)
    # whitespace runs are collapsed before encoding
    assert np.array_equal(encoder.encode(["  a person\twalks "]), encoder.encode(["a person walks"]))


def test_unnormalized_is_the_mean_pooled_vector(encoder):
    raw = encoder.encode(["a person walks", "a person bows"], normalize=False)
    norms = np.linalg.norm(raw, axis=1)
    assert np.all(norms > 3.0)                                          # ~6 for these texts
    np.testing.assert_allclose(raw / norms[:, None], encoder.encode(["a person walks",
                                                                     "a person bows"]), atol=1e-6)


def test_semantic_sanity_and_reference_numbers(encoder):
    walk, stroll, bow, hop, jump, wave = encoder.encode([
        "a person walks", "a person strolls", "a person bows", "a person hops",
        "a person jumps", "a person waves"])
    assert walk @ stroll > walk @ bow
    assert hop @ jump > hop @ wave
    assert walk @ stroll == pytest.approx(0.8527, abs=2e-3)            # measured, CPU
    assert hop @ jump == pytest.approx(0.6713, abs=2e-3)


# ----------------------------------------------------------------------------- inputs


@pytest.mark.parametrize("bad, exc", [
    ("", ValueError), ("   \t", ValueError), ([""], ValueError),
    (["a person walks", "  "], ValueError), (None, TypeError), (3, TypeError),
    (b"a person walks", TypeError), (["a person walks", 5], TypeError),
    ({"a person walks": 1}, TypeError),
])
def test_bad_inputs_raise_before_any_loading(bad, exc):
    enc = ActionEncoder()
    with pytest.raises(exc, match="action|texts"):
        enc.encode(bad)
    assert not enc.loaded
    with pytest.raises(exc):
        EmbeddingCache(encoder=BagOfWords()).get(bad)


def test_error_messages_say_what_to_do():
    with pytest.raises(ValueError, match=r"texts\[1\] is empty.*'a person walks'"):
        ActionEncoder().encode(["a person walks", " "])
    with pytest.raises(TypeError, match=r"texts\[1\] must be a str, got int"):
        ActionEncoder().encode(["a person walks", 5])


def test_action_prompt():
    assert action_prompt("walk") == "a person walks"
    assert action_prompt(" Wave-Right-Hand ") == "a person waves the right hand"
    assert action_prompt("a person  hops") == "a person hops"
    assert action_prompt("does a backflip") == "a person does a backflip"
    with pytest.raises(ValueError):
        action_prompt(" ")


def test_training_vocabulary():
    plain, styled = training_vocabulary(), training_vocabulary(styles=True)
    assert len(plain) == len(set(ACTION_PHRASES.values())) == 24
    assert len(styled) == len(set(styled)) == 432 and styled[:24] == plain
    assert {action_text(c, s) for c in ACTION_PHRASES for s in STYLE_PHRASES} == set(styled)
    demo = demo_vocabulary()
    assert demo[:24] == plain and "a person jumps" in demo and len(demo) == len(set(demo))


# ----------------------------------------------------------------------------- cache


def test_cache_matches_encoder_and_needs_no_encoder_after_loading(tmp_path, encoder,
                                                                   vocab_cache):
    texts = ["a person walks", "a person waves the right hand happily", "a person bows"]
    path = vocab_cache.save(tmp_path / "vocab.npz")
    fresh = EmbeddingCache.load(path)
    assert len(fresh) == len(vocab_cache) == 92 and fresh.encoder_name == encoder.name
    E = fresh.get(texts)                                   # encoder=None: table only
    assert fresh.n_encoded == 0 and fresh.encoder is None
    assert E.shape == (3, EMBED_DIM) and E.dtype == np.float32
    assert np.array_equal(E, vocab_cache.get(texts))                    # saved bit-exactly
    np.testing.assert_allclose(E, encoder.encode(texts), atol=1e-6)     # = the encoder
    assert fresh.get("a person walks").shape == (EMBED_DIM,)
    assert np.array_equal(fresh(["a person bows"]), E[2:])             # the seam


def test_unknown_texts_go_through_the_encoder(encoder):
    cache = EmbeddingCache.build(training_vocabulary(), encoder)
    assert cache.n_encoded == 24
    hop = cache.get("a person hops", encoder=encoder)
    assert cache.n_encoded == 25 and "a person hops" in cache
    np.testing.assert_allclose(hop, encoder.encode(["a person hops"])[0], atol=1e-6)
    cache.get(["a person hops", "a person walks"])                      # both known now
    assert cache.n_encoded == 25
    cache.get("a person jumps", encoder=encoder, add=False)
    assert cache.n_encoded == 26 and "a person jumps" not in cache


def test_default_encoder_is_created_only_for_unknown_texts(monkeypatch):
    made = []

    class FakeEncoder(BagOfWords):
        def __init__(self):
            super().__init__()
            made.append(self)

    monkeypatch.setattr(T, "ActionEncoder", FakeEncoder)
    cache = EmbeddingCache(["a person walks"], [[1.0, 1.0, 0.0, 0.0, 0.0]])
    cache.get(["a person walks"])
    assert made == [] and cache.encoder is None
    cache.get("a person runs")
    cache.get("a person waves")
    assert len(made) == 1 and cache.encoder is made[0]                  # created once, reused
    assert made[0].calls == [["a person runs"], ["a person waves"]]


def test_cache_with_a_custom_encoder_analytic():
    bow = BagOfWords()
    cache = EmbeddingCache.build(["a person walks", "a person  walks", "a person runs"], bow)
    assert cache.texts == ["a person walks", "a person runs"] and cache.dim == 5
    np.testing.assert_allclose(cache.get("a person walks"), np.array([1, 1, 0, 0, 0]) / 2**0.5)
    assert cache.encoder_name == "bag-of-words"
    with pytest.raises(ValueError, match="do not share a space"):
        cache.get("a person bows", encoder=ActionEncoder())             # name differs; not loaded
    with pytest.raises(ValueError, match=r"returned shape \(1, 3\)"):
        cache.get("a person bows", encoder=lambda texts: np.ones((len(texts), 3)))
    with pytest.raises(ValueError, match="distinct"):
        EmbeddingCache(["a person walks", "a person walks"], np.ones((2, 5)))


def test_state_dict_round_trip():
    cache = EmbeddingCache.build(["a person walks", "a person bows"], BagOfWords())
    back = EmbeddingCache.from_state_dict(cache.state_dict())
    assert back.texts == cache.texts and back.encoder_name == "bag-of-words"
    assert np.array_equal(back.embeddings, cache.embeddings)
    with pytest.raises(ValueError, match="missing"):
        EmbeddingCache.from_state_dict({"texts": np.array(["a"])})
    with pytest.raises(FileNotFoundError, match="build one"):
        EmbeddingCache.load("/nonexistent/vocab.npz")


def test_known_words_and_corrupt_weights_never_import_torch(tmp_path, corrupt_model_dir):
    """In a fresh interpreter: looking up / ranking known texts from a saved cache, and
    refusing corrupt weights, import neither torch nor sentence-transformers."""
    path = EmbeddingCache.build(training_vocabulary(), BagOfWords()).save(tmp_path / "c.npz")
    code = textwrap.dedent(f"""
        import json, sys
        from physlab.motion.text import (ActionEncoder, EmbeddingCache, WeightsChecksumError,
                                         action_prompt, nearest)
        cache = EmbeddingCache.load({str(path)!r})
        E = cache.get([action_prompt("walk"), action_prompt("bow")])
        near = nearest("a person walks", cache, k=2)
        try:
            ActionEncoder(model_dir={str(corrupt_model_dir)!r}).load()
            refused = False
        except WeightsChecksumError:
            refused = True
        print(json.dumps({{"shape": E.shape, "n_encoded": cache.n_encoded, "near": near,
                           "refused": refused,
                           "heavy": [m for m in ("torch", "sentence_transformers",
                                                 "transformers") if m in sys.modules]}}))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    res = json.loads(out.strip().splitlines()[-1])
    assert res["heavy"] == [] and res["refused"] and res["n_encoded"] == 0
    assert res["shape"] == [2, 5] and res["near"][0][0] == "a person walks"
    assert res["near"][0][1] == pytest.approx(1.0, abs=1e-6)


# ----------------------------------------------------------------------------- neighbours


def test_cosine_similarity_analytic():
    S = cosine_similarity([[1.0, 0.0], [1.0, 1.0]], [[2.0, 0.0], [0.0, 3.0], [-1.0, -1.0]])
    r = 2 ** -0.5
    np.testing.assert_allclose(S, [[1, 0, -r], [r, r, -1]], atol=1e-12)
    with pytest.raises(ValueError, match="same width"):
        cosine_similarity(np.ones((1, 2)), np.ones((1, 3)))


def test_nearest_analytic_with_the_seam():
    vocab = ["a person runs", "a person sits", "a person walks"]
    # (1,1,0,0,0) vs runs (1,0,1,0,0): 1/2; sits (1,0,0,0,0): 1/sqrt 2; walks: 1
    got = nearest("a person walks happily", vocab, k=3, encoder=BagOfWords())
    assert [w for w, _ in got] == ["a person walks", "a person sits", "a person runs"]
    np.testing.assert_allclose([c for _, c in got], [1.0, 2 ** -0.5, 0.5], atol=1e-6)
    assert len(nearest("a person walks", vocab, k=10, encoder=BagOfWords())) == 3
    for k in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="k must be"):
            nearest("a person walks", vocab, k=k, encoder=BagOfWords())
    with pytest.raises(ValueError, match="empty"):
        nearest("a person walks", [], encoder=BagOfWords())
    with pytest.raises(TypeError):
        nearest(["a person walks"], vocab, encoder=BagOfWords())
    with pytest.raises(ValueError):
        nearest(" ", vocab, encoder=BagOfWords())


def test_nearest_in_the_real_vocabulary(encoder, vocab_cache):
    # stroll -> walk; jog -> run; greet -> a gesture of the Bandai vocabulary
    assert nearest("a person strolls", training_vocabulary(), k=1,
                   encoder=encoder)[0][0] == "a person walks"
    assert nearest("a person jogs", training_vocabulary(), k=1,
                   encoder=encoder)[0][0] == "a person runs"
    greet = [w for w, _ in nearest("a person greets someone", training_vocabulary(), k=3,
                                   encoder=encoder)]
    assert "a person responds with a gesture" in greet
    # Bandai-Namco has no jump: with the generic actions added, "hops" lands on "jumps"
    (w_self, c_self), (w0, c0), (_, c1) = nearest("a person hops", vocab_cache, k=3)
    assert w_self == "a person hops" and c_self == pytest.approx(1.0, abs=1e-6)
    assert w0 == "a person jumps" and c0 > c1
    n = vocab_cache.n_encoded
    nearest("a person walks", vocab_cache, k=3)                         # known: no encoding
    assert vocab_cache.n_encoded == n
