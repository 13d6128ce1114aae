"""all-MiniLM-L6-v2's forward pass in plain PyTorch: physlab's text encoder without
sentence-transformers.

:class:`~physlab.motion.text.ActionEncoder` embeds action words with all-MiniLM-L6-v2
(a 6-layer BERT, hidden size 384, 12 heads, mean pooling). Importing sentence-transformers
(and with it transformers) takes 5-7 s on a 2-core CPU, longer than a lesson can afford, for
a network of a few hundred lines of arithmetic. This module runs the same arithmetic from
the same two files of the model folder:

* ``tokenizer.json`` read by the ``tokenizers`` library (the Rust WordPiece tokenizer that
  sentence-transformers runs too): lower-casing, ``[CLS] ... [SEP]``, at most
  :data:`MAX_TOKENS` tokens (sentence-transformers' ``max_seq_length`` of this model);
* ``model.safetensors`` read by ``safetensors`` into :class:`MiniLM`.

The forward pass is BERT's (Devlin et al. 2019), in inference mode (no dropout):

    h⁰ = LN(E_word[ids] + E_pos[0..L) + E_type[0])
    per layer:  a = LN(h + W_o · softmax(Q Kᵀ / √d_head + m) V)     (12 heads of 32)
                h = LN(a + W_2 · gelu(W_1 a))                         (gelu with erf)
    e = Σ_i mask_i h_i / Σ_i mask_i                                    (mean pooling)

with ``m`` = -inf-like on padding keys and LN's ε = 1e-12 (the model's ``config.json``).
``tests/motion/test_minilm.py`` checks it against sentence-transformers (the reference
library, still a test dependency) and against the embeddings in the shipped checkpoint's
text cache, which sentence-transformers made.

torch is imported by this module: import it lazily (``ActionEncoder.load`` does).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch
from torch import nn

__all__ = ["MAX_TOKENS", "MiniLM", "load_minilm"]

#: Longest token sequence (sentence-transformers' ``max_seq_length`` for all-MiniLM-L6-v2);
#: longer texts are cut, as sentence-transformers cuts them.
MAX_TOKENS = 256

_CONFIG_KEYS = ("hidden_size", "num_attention_heads", "num_hidden_layers", "intermediate_size",
                "vocab_size", "max_position_embeddings", "type_vocab_size", "layer_norm_eps",
                "hidden_act")


class _Layer(nn.Module):
    """One BERT encoder layer (post-LN): self-attention, then the feed-forward block."""

    def __init__(self, d, heads, d_ff, eps):
        super().__init__()
        self.heads = heads
        self.qkv = nn.Linear(d, 3 * d)
        self.out = nn.Linear(d, d)
        self.ln1 = nn.LayerNorm(d, eps=eps)
        self.ff1 = nn.Linear(d, d_ff)
        self.ff2 = nn.Linear(d_ff, d)
        self.ln2 = nn.LayerNorm(d, eps=eps)

    def forward(self, h, key_bias):
        B, L, d = h.shape
        q, k, v = self.qkv(h).view(B, L, 3, self.heads, d // self.heads).permute(2, 0, 3, 1, 4)
        scores = q @ k.transpose(-1, -2) / (d // self.heads) ** 0.5 + key_bias  # (B, H, L, L)
        ctx = (scores.softmax(-1) @ v).transpose(1, 2).reshape(B, L, d)
        a = self.ln1(h + self.out(ctx))
        return self.ln2(a + self.ff2(nn.functional.gelu(self.ff1(a))))


class MiniLM(nn.Module):
    """BERT encoder + mean pooling (all-MiniLM-L6-v2's architecture), inference only.

    Parameters
    ----------
    config : dict with the keys of a BERT ``config.json`` (hidden_size, num_attention_heads,
        num_hidden_layers, intermediate_size, vocab_size, max_position_embeddings,
        type_vocab_size, layer_norm_eps, hidden_act = "gelu").

    ``forward(ids, mask)``: ``ids`` (B, L) int64 token ids, ``mask`` (B, L) 1 for tokens,
    0 for padding -> (B, hidden_size) mean-pooled token states (not normalised).
    """

    def __init__(self, config):
        super().__init__()
        missing = [k for k in _CONFIG_KEYS if k not in config]
        if missing:
            raise ValueError(f"the model config lacks {missing}; it must be a BERT config.json")
        if config["hidden_act"] != "gelu":
            raise ValueError(f"hidden_act {config['hidden_act']!r} is not supported (gelu only)")
        d, eps = int(config["hidden_size"]), float(config["layer_norm_eps"])
        if d % int(config["num_attention_heads"]):
            raise ValueError("hidden_size must be a multiple of num_attention_heads")
        self.word = nn.Embedding(int(config["vocab_size"]), d)
        self.pos = nn.Embedding(int(config["max_position_embeddings"]), d)
        self.token_type = nn.Embedding(int(config["type_vocab_size"]), d)
        self.ln = nn.LayerNorm(d, eps=eps)
        self.layers = nn.ModuleList(
            _Layer(d, int(config["num_attention_heads"]), int(config["intermediate_size"]), eps)
            for _ in range(int(config["num_hidden_layers"])))

    @torch.no_grad()
    def forward(self, ids, mask):
        L = ids.shape[1]
        h = self.ln(self.word(ids) + self.pos.weight[:L] + self.token_type.weight[0])
        m = mask.to(h.dtype)
        key_bias = (1.0 - m)[:, None, None, :] * torch.finfo(h.dtype).min      # (B, 1, 1, L)
        for layer in self.layers:
            h = layer(h, key_bias)
        return (h * m[..., None]).sum(1) / m.sum(1, keepdim=True).clamp_min(1e-9)

    def load_bert_state(self, state):
        """Copy the tensors of a Hugging Face ``BertModel`` state dict (names as in
        ``model.safetensors``, with or without a ``bert.`` prefix) into this module.
        ValueError naming the first missing tensor or shape mismatch."""
        state = {k.removeprefix("bert."): v for k, v in state.items()}

        def get(name):
            if name not in state:
                raise ValueError(f"the weights lack {name!r}: not a BERT model.safetensors")
            return state[name]

        own = {"word.weight": get("embeddings.word_embeddings.weight"),
               "pos.weight": get("embeddings.position_embeddings.weight"),
               "token_type.weight": get("embeddings.token_type_embeddings.weight"),
               "ln.weight": get("embeddings.LayerNorm.weight"),
               "ln.bias": get("embeddings.LayerNorm.bias")}
        for i in range(len(self.layers)):
            p = f"encoder.layer.{i}."
            for part in ("weight", "bias"):
                own[f"layers.{i}.qkv.{part}"] = torch.cat(
                    [get(f"{p}attention.self.{n}.{part}") for n in ("query", "key", "value")])
                own[f"layers.{i}.out.{part}"] = get(f"{p}attention.output.dense.{part}")
                own[f"layers.{i}.ln1.{part}"] = get(f"{p}attention.output.LayerNorm.{part}")
                own[f"layers.{i}.ff1.{part}"] = get(f"{p}intermediate.dense.{part}")
                own[f"layers.{i}.ff2.{part}"] = get(f"{p}output.dense.{part}")
                own[f"layers.{i}.ln2.{part}"] = get(f"{p}output.LayerNorm.{part}")
        mine = self.state_dict()
        for name, t in own.items():
            if tuple(t.shape) != tuple(mine[name].shape):
                raise ValueError(f"weight {name}: shape {tuple(t.shape)} in the file, "
                                 f"{tuple(mine[name].shape)} in the config")
        self.load_state_dict({k: v.float() for k, v in own.items()})
        return self


class _Encoder:
    """Tokenizer + :class:`MiniLM`: ``encode(list of str, batch_size) -> (N, D)`` float32
    mean-pooled vectors (the interface ``ActionEncoder`` needs from a backend)."""

    def __init__(self, tokenizer, model, device="cpu"):
        self.tokenizer, self.model, self.device = tokenizer, model.to(device), device

    def encode(self, texts, batch_size=64):
        # batches of similar lengths pad little (sentence-transformers sorts the same way);
        # padding does not change a text's vector beyond float32 round-off
        order = np.argsort([-len(t) for t in texts], kind="stable")
        out = np.zeros((len(texts), self.model.word.embedding_dim), dtype=np.float32)
        for i in range(0, len(texts), batch_size):
            rows = order[i:i + batch_size]
            enc = self.tokenizer.encode_batch([texts[j] for j in rows])
            ids = torch.tensor([e.ids for e in enc], dtype=torch.long, device=self.device)
            mask = torch.tensor([e.attention_mask for e in enc], device=self.device)
            out[rows] = self.model(ids, mask).cpu().numpy()
        return out


def load_minilm(model_dir, device="cpu"):
    """Read an all-MiniLM-L6-v2 folder (``config.json``, ``tokenizer.json``,
    ``model.safetensors``) into an encoder with ``encode(texts, batch_size)`` on ``device``.
    FileNotFoundError naming a missing file. Does not check the weights' digest
    (``ActionEncoder.load`` does that first)."""
    from safetensors.torch import load_file
    from tokenizers import Tokenizer

    model_dir = Path(model_dir)
    for name in ("config.json", "tokenizer.json", "model.safetensors"):
        if not (model_dir / name).is_file():
            raise FileNotFoundError(f"{model_dir / name} is missing: not an all-MiniLM-L6-v2 "
                                    f"folder")
    config = json.loads((model_dir / "config.json").read_text())
    tokenizer = Tokenizer.from_file(str(model_dir / "tokenizer.json"))
    tokenizer.enable_truncation(MAX_TOKENS)
    tokenizer.enable_padding(pad_id=int(config.get("pad_token_id", 0)))   # to the longest
    model = MiniLM(config).load_bert_state(load_file(str(model_dir / "model.safetensors")))
    return _Encoder(tokenizer, model.eval(), device)
