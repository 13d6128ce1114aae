"""Tests of physlab.motion.minilm: physlab's own all-MiniLM-L6-v2 forward pass, checked
against the reference library (sentence-transformers) and against the embeddings that
library put into the shipped checkpoint's text cache."""
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from physlab.motion.minilm import MAX_TOKENS, MiniLM, load_minilm
from physlab.motion.text import (GENERIC_ACTIONS, ActionEncoder, EmbeddingCache,
                                 default_model_dir, training_vocabulary)

TEXTS = training_vocabulary()[:12] + list(GENERIC_ACTIONS[:6]) + [
    "x", "A PERSON WALKS!", "Ünïcödé façade — naïve café, 3.5 m/s?",
    "a person " + "walks and " * 150 + "stops",            # > 256 tokens: cut like the reference
]


@pytest.fixture(scope="module")
def ours():
    return ActionEncoder(num_threads=1, backend="physlab").load()


@pytest.fixture(scope="module")
def reference():
    return ActionEncoder(num_threads=1, backend="sentence-transformers").load()


def test_equals_sentence_transformers(ours, reference):
    A = ours.encode(TEXTS, normalize=False)
    R = reference.encode(TEXTS, normalize=False)
    assert A.shape == R.shape == (len(TEXTS), 384)
    rel = np.abs(A - R).max(axis=1) / np.linalg.norm(R, axis=1)
    assert rel.max() < 1e-5, rel.max()                          # measured 1.7e-7
    # the long text was cut at MAX_TOKENS: its vector differs from a shorter repetition's
    assert len(ours._model.tokenizer.encode(TEXTS[-1]).ids) == MAX_TOKENS
    assert ours.name == reference.name                             # one embedding space
    # batches of any size give the same vectors (padding is masked out)
    small = ActionEncoder(num_threads=1, batch_size=3).encode(TEXTS, normalize=False)
    np.testing.assert_allclose(small, A, rtol=0, atol=1e-5)


def test_reproduces_the_shipped_text_cache(ours):
    """The shipped checkpoint's cache was made by sentence-transformers: physlab's forward
    pass must give the same unit vectors for every text the model was trained with."""
    from physlab.motion.checkpoint import load_checkpoint
    from physlab.motion.sampling import DEFAULT_CHECKPOINT

    cache = EmbeddingCache.from_state_dict(load_checkpoint(DEFAULT_CHECKPOINT)["text_cache"])
    E = ours.encode(list(cache.texts))
    assert np.abs(E - cache.embeddings).max() < 1e-5               # measured 1.6e-7


def test_does_not_import_sentence_transformers():
    code = textwrap.dedent("""
        import sys
        from physlab.motion.text import ActionEncoder
        E = ActionEncoder(num_threads=1).encode(["a person walks"])
        assert E.shape == (1, 384)
        print("sentence_transformers" in sys.modules, "transformers" in sys.modules)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "False"]


def test_bad_folders_and_weights_are_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="config.json is missing"):
        load_minilm(tmp_path)
    with pytest.raises(ValueError, match="backend must be one of"):
        ActionEncoder(backend="onnx")
    config = {"hidden_size": 8, "num_attention_heads": 2, "num_hidden_layers": 1,
              "intermediate_size": 16, "vocab_size": 10, "max_position_embeddings": 12,
              "type_vocab_size": 2, "layer_norm_eps": 1e-12, "hidden_act": "gelu"}
    with pytest.raises(ValueError, match="lacks.*layer_norm_eps"):
        MiniLM({k: v for k, v in config.items() if k != "layer_norm_eps"})
    with pytest.raises(ValueError, match="hidden_act 'relu'"):
        MiniLM(dict(config, hidden_act="relu"))
    model = MiniLM(config)
    with pytest.raises(ValueError, match="lack 'embeddings.word_embeddings.weight'"):
        model.load_bert_state({})
    import torch
    from safetensors.torch import load_file

    real = load_file(str(default_model_dir() / "model.safetensors"))
    with pytest.raises(ValueError, match="word.weight: shape"):
        model.load_bert_state(real)                            # 384-wide weights, 8-wide model
    # a (randomly initialised) tiny model runs, and padding does not change a text's vector
    ids = torch.tensor([[1, 2, 3, 0], [1, 2, 3, 4]])
    mask = torch.tensor([[1, 1, 1, 0], [1, 1, 1, 1]])
    h = model(ids, mask)
    assert h.shape == (2, 8) and torch.isfinite(h).all()
    np.testing.assert_allclose(model(ids[:1, :3], mask[:1, :3]), h[:1], atol=1e-6)
