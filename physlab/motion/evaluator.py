"""Text–motion evaluator: FID, R-precision, MM-Dist and Diversity of 40-frame motions, offline
on a CPU.

The metrics of Guo et al. 2022 ("Generating Diverse and Natural 3D Human Motions from Text",
the HumanML3D benchmark that MLD, MDM and Sketch2Anim report) compare motions in the
embedding space of a contrastively trained text–motion model. The HumanML3D evaluator does
not fit Bandai-Namco windows (other skeleton, other texts) and its download links keep
breaking, so physlab trains its own, TMR-style (Petrovich et al. 2023, "TMR: Text-to-Motion
Retrieval Using Contrastive 3D Human Motion Synthesis"), on the training takes only:

* **motion side** — :func:`motion_features` turns a canonical window ``(40, 22, 3)`` (m,
  20 fps, frame-0 pelvis at ``x = z = 0`` facing ``+z``; :func:`~physlab.motion.dataset.
  make_windows`) into 69 numbers per frame: pelvis position (3) and velocity (3) and the
  pelvis-relative joints (63), normalised by statistics stored in the checkpoint; a small
  transformer (:class:`MotionEncoder`, a CLS token, 3 pre-norm layers of width 128) maps
  them to a unit vector ``m`` of ``D = 256``;
* **text side** — the 384-d all-MiniLM-L6-v2 sentence embedding of the text
  (:mod:`physlab.motion.text`) through a 2-layer MLP (:class:`TextProjection`) to a unit
  vector ``t`` of ``D``; the MiniLM embeddings of the training vocabulary are stored in the
  checkpoint, so scoring known texts never loads the sentence encoder;
* **loss** — symmetric InfoNCE (van den Oord et al. 2018, as in CLIP and TMR):
  ``L = ½ [CE(S, I) + CE(Sᵀ, I)]`` with ``S_ij = m_i · t_j / τ`` (:func:`info_nce`). Many
  windows share one text (5805 training windows, 210 texts), so a window's other windows of
  the same text are removed from its negatives (TMR filters negatives whose texts are alike
  for the same reason);
* **augmentation** — mirroring (:func:`mirror_joints`: reflect ``x``, swap left / right
  joints) with the text mirrored too (:func:`mirror_text`: "waves the left hand" <-> "waves
  the right hand"), half of every batch.

Metrics (pure numpy on embeddings, Guo et al. 2022 definitions as in the HumanML3D /
MLD evaluation code): :func:`fid`, :func:`r_precision` (with :func:`r_precision_chance`),
:func:`mm_dist`, :func:`diversity`, all in :func:`evaluate_embeddings`. Embeddings are unit
vectors, so distances lie in ``[0, 2]`` and the numbers are on another scale than the
HumanML3D evaluator's (real HumanML3D: MM-Dist ≈ 3.0, Diversity ≈ 9.5); compare rows of one
table, not with papers.

Use::

    from physlab.motion.evaluator import TextMotionEvaluator
    ev = TextMotionEvaluator.from_checkpoint()            # data/motion/text_motion_evaluator.pt
    m = ev.encode_motion(joints)                          # (N, 40, 22, 3) -> (N, 256)
    t = ev.encode_text(["a person walks", ...])           # (N, 256)
    ev.evaluate(real_joints, gen_joints, texts)           # {"fid", "r_precision_top1", ...}

    python -m physlab.motion.evaluator train --out runs/motion/evaluator.pt \\
        --export data/motion/text_motion_evaluator.pt --steps 1000      # ~7 min, 1 thread
    python -m physlab.motion.evaluator train --smoke --out /tmp/ev.pt     # seconds
    python -m physlab.motion.evaluator check                               # held-out sanity

Data: Bandai-Namco-Research-Motiondataset, CC BY-NC 4.0, © 2022 Bandai Namco Research Inc.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from .checkpoint import (CHECKPOINT_KIND, CHECKPOINT_VERSION, NOTHING_LEFT_TO_TRAIN,
                         export_weights, load_checkpoint, save_checkpoint)
from .dataset import (MIRROR_PERMUTATION, mirror_joints, mirror_text,  # noqa: F401
                      BANDAI_NAMCO_ATTRIBUTION, TEST_TAKES, load_clips, make_windows,
                      read_labels, split_by_take)
from .skeleton import JOINT_NAMES
from .train import warmup_cosine_lr

__all__ = [
    "DEFAULT_EVALUATOR", "FEATURE_DIM", "STAGE", "SMOKE_MODEL", "EvaluatorConfig",
    "EvaluatorTrainConfig", "MotionEncoder", "TextProjection", "TextMotionModel",
    "TextMotionEvaluator", "motion_features", "mirror_joints", "mirror_text",
    "MIRROR_PERMUTATION", "info_nce", "euclidean_distance_matrix", "fid", "r_precision",
    "r_precision_chance", "mm_dist", "diversity", "evaluate_embeddings", "held_out_data",
    "sanity_report", "format_report", "train", "main",
]

#: The shipped evaluator (fp16 inference copy; ``python -m physlab.motion.evaluator train``).
DEFAULT_EVALUATOR = Path(__file__).resolve().parents[2] / "data" / "motion" / \
    "text_motion_evaluator.pt"
#: ``stage`` of an evaluator checkpoint (the generator's are ``"base"`` / ``"control"``).
STAGE = "evaluator"
#: Numbers per frame of :func:`motion_features`: pelvis (3), pelvis velocity (3),
#: pelvis-relative joints (21 x 3).
FEATURE_DIM = 3 + 3 + 63

#: Model of ``--smoke`` runs: a few seconds on a CPU.
SMOKE_MODEL = {"d_model": 32, "n_heads": 2, "n_layers": 1, "ff": 64, "embed_dim": 16,
               "text_hidden": 32, "dropout": 0.0}


# ----------------------------------------------------------------------------- config


@dataclass
class EvaluatorConfig:
    """Network sizes; saved in the checkpoint and used to rebuild the model."""

    n_frames: int = 40              # frames per window (Sketch2Anim N = 40, 2 s at 20 fps)
    feature_dim: int = FEATURE_DIM  # numbers per frame (motion_features)
    text_dim: int = 384             # MiniLM sentence embedding width
    d_model: int = 128              # transformer width of the motion encoder
    n_heads: int = 4                # attention heads
    n_layers: int = 3               # transformer layers
    ff: int = 256                   # feed-forward width
    dropout: float = 0.1            # dropout in the transformer and the text MLP
    embed_dim: int = 256            # D, width of the joint embedding space
    text_hidden: int = 256          # hidden width of the text projection MLP

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "dropout":
                if not 0 <= v < 1:
                    raise ValueError(f"dropout must be in [0, 1), got {v}")
            elif isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{f.name} must be an integer >= 1, got {v!r}")
        if self.d_model % self.n_heads:
            raise ValueError(f"d_model={self.d_model} must be divisible by n_heads="
                             f"{self.n_heads}")

    def to_dict(self):
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d):
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


@dataclass
class EvaluatorTrainConfig:
    """Training settings; saved in the checkpoint. Field names = CLI flags."""

    out: str = ""                   # checkpoint (atomic; resumed from if it exists); "" =
                                    # runs/motion/evaluator.pt (smoke_evaluator.pt with --smoke)
    export: str = ""                # after training, write an fp16 inference copy here
    resume: bool = True             # continue from `out` if it exists
    seed: int = 0                   # seeds initialisation, batches, mirroring, dropout
    steps: int = 1000               # optimiser steps in total (resume continues up to it)
    batch_size: int = 128           # windows per step
    lr: float = 5e-4                # peak AdamW learning rate
    min_lr: float = 2e-5            # cosine decay floor
    warmup: int = 100               # linear warm-up steps
    weight_decay: float = 0.01      # AdamW weight decay
    grad_clip: float = 1.0          # max global gradient norm (0 = off)
    temperature: float = 0.1        # InfoNCE temperature τ (TMR: 0.1)
    mirror: bool = True             # mirror half of every batch (joints and text)
    checkpoint_every: int = 250     # steps between checkpoints (and at the end)
    num_threads: int = 1            # torch threads (1: deterministic and polite)
    data_root: str = ""             # Bandai-Namco folder; "" = <external data>/mocap/bandai_namco
    max_clips: int = 0              # use only the first k training clips (0 = all)
    window_stride: int = 10         # frames between window starts (40-frame windows)
    text_encoder: str = "minilm"    # "minilm" (text.ActionEncoder) | "hash" (tests: fake)
    text_cache: str = ""            # optional EmbeddingCache .npz to read / fill
    smoke: bool = False             # tiny model, few steps, few clips: seconds
    progress: bool = True           # tqdm bar

    def __post_init__(self):
        if self.text_encoder not in ("minilm", "hash"):
            raise ValueError(f"text_encoder must be 'minilm' or 'hash', got "
                             f"{self.text_encoder!r}")
        for name in ("steps", "batch_size", "checkpoint_every", "window_stride", "num_threads"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if self.batch_size < 2:
            raise ValueError(f"batch_size must be >= 2 (InfoNCE needs negatives), got "
                             f"{self.batch_size}")
        for name in ("lr", "min_lr", "weight_decay", "grad_clip", "temperature"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
        if not 0 < self.lr <= 1:
            raise ValueError(f"lr must be in (0, 1], got {self.lr}")
        if not 0 <= self.min_lr <= self.lr:
            raise ValueError(f"min_lr must be in [0, lr = {self.lr}], got {self.min_lr}")
        if not 0 < self.temperature <= 10:
            raise ValueError(f"temperature must be in (0, 10] (TMR uses 0.1), got "
                             f"{self.temperature}")
        for name in ("warmup", "weight_decay", "grad_clip", "max_clips", "seed"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not self.out:
            self.out = ("runs/motion/smoke_evaluator.pt" if self.smoke
                        else "runs/motion/evaluator.pt")


# ----------------------------------------------------------------------------- features


def _check_motion(joints, name="joints", n_frames=None):
    """``joints`` as a finite float array of shape ``(N, T, 22, 3)``; ValueError naming
    ``name`` otherwise."""
    x = np.asarray(joints)
    if x.dtype == object or not np.issubdtype(x.dtype, np.number):
        raise ValueError(f"{name} must be a numeric array of shape (N, T, 22, 3), got dtype "
                         f"{x.dtype}")
    if x.ndim != 4 or x.shape[2:] != (len(JOINT_NAMES), 3):
        raise ValueError(f"{name} must have shape (N, T, 22, 3) (windows of 22 joints in m), "
                         f"got {x.shape}; a single window needs a leading axis: x[None]")
    if n_frames is not None and x.shape[1] != n_frames:
        raise ValueError(f"{name} has {x.shape[1]} frames per window; the evaluator reads "
                         f"{n_frames}-frame windows (physlab.motion.dataset.make_windows)")
    if len(x) == 0:
        raise ValueError(f"{name} is empty (N = 0); give at least one window")
    if not np.all(np.isfinite(x)):
        bad = int(np.argwhere(~np.isfinite(x).all(axis=(1, 2, 3)))[0, 0])
        raise ValueError(f"{name} contains NaN or inf (first in window {bad})")
    return x


def motion_features(joints):
    """Per-frame input of the motion encoder.

    Parameters
    ----------
    joints : (N, T, 22, 3) float array or tensor, canonical windows (m, y up), frame rate
        20 Hz (velocities are per frame).

    Returns
    -------
    (N, T, 69) float32 tensor: pelvis position ``p`` (3), pelvis velocity ``p[t] - p[t-1]``
    (3, zero at frame 0) and the pelvis-relative positions ``x_j - p`` of the 21 other
    joints (63). No joint velocities: with them, per-dimension standardisation made 5 mm of
    frame-to-frame jitter look like another action (R-precision top-3 of held-out windows
    1.00 -> 0.36); jitter is measured by the jerk metrics instead.
    """
    x = torch.as_tensor(joints, dtype=torch.float32)                          # (N, T, 22, 3)
    N, T = x.shape[:2]
    root = x[:, :, 0]                                                         # (N, T, 3)
    rel = (x[:, :, 1:] - root[:, :, None]).reshape(N, T, -1)                  # (N, T, 63)
    v_root = torch.cat([torch.zeros_like(root[:, :1]), root[:, 1:] - root[:, :-1]], dim=1)
    return torch.cat([root, v_root, rel], dim=-1)                             # (N, T, 69)


# ----------------------------------------------------------------------------- networks


class MotionEncoder(nn.Module):
    """Normalised window features ``(B, T, F)`` -> unit embeddings ``(B, D)``.

    A linear input layer, a learned CLS token prepended, learned positional embeddings,
    ``n_layers`` pre-norm transformer layers (GELU), a final LayerNorm and a linear map of
    the CLS output to ``D`` (TMR's motion encoder without the VAE's variance token)."""

    def __init__(self, cfg: EvaluatorConfig):
        super().__init__()
        self.config = cfg
        self.inp = nn.Linear(cfg.feature_dim, cfg.d_model)
        self.cls = nn.Parameter(torch.zeros(1, 1, cfg.d_model))
        self.pos = nn.Parameter(0.02 * torch.randn(1, cfg.n_frames + 1, cfg.d_model))
        layer = nn.TransformerEncoderLayer(cfg.d_model, cfg.n_heads, cfg.ff, cfg.dropout,
                                           activation="gelu", batch_first=True,
                                           norm_first=True)
        self.encoder = nn.TransformerEncoder(layer, cfg.n_layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(cfg.d_model)
        self.out = nn.Linear(cfg.d_model, cfg.embed_dim)

    def forward(self, f):
        B = f.shape[0]
        h = self.inp(f)                                                       # (B, T, C)
        h = torch.cat([self.cls.expand(B, -1, -1), h], dim=1) + self.pos      # (B, T+1, C)
        h = self.norm(self.encoder(h)[:, 0])                                  # (B, C)
        return F.normalize(self.out(h), dim=-1)                               # (B, D)


class TextProjection(nn.Module):
    """MiniLM sentence embeddings ``(B, 384)`` -> unit embeddings ``(B, D)`` (2-layer MLP)."""

    def __init__(self, cfg: EvaluatorConfig):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(cfg.text_dim, cfg.text_hidden), nn.GELU(),
                                 nn.Dropout(cfg.dropout),
                                 nn.Linear(cfg.text_hidden, cfg.embed_dim))

    def forward(self, a):
        return F.normalize(self.net(a), dim=-1)                               # (B, D)


class TextMotionModel(nn.Module):
    """The two encoders of the evaluator; ``forward(features, text_emb) -> (m, t)``."""

    def __init__(self, cfg: EvaluatorConfig):
        super().__init__()
        self.config = cfg
        self.motion = MotionEncoder(cfg)
        self.text = TextProjection(cfg)

    def forward(self, f, a):
        return self.motion(f), self.text(a)


def info_nce(m, t, text_index, temperature=0.1):
    """Symmetric InfoNCE of matched motion / text embeddings (van den Oord et al. 2018;
    CLIP; TMR, Petrovich et al. 2023), same-text negatives removed.

    ``S_ij = m_i · t_j / τ``; entries ``i != j`` with ``text_index[i] == text_index[j]`` are
    set to ``-inf`` (they are not negatives: the motion does match that text);
    ``L = ½ [CE(S, I) + CE(Sᵀ, I)]`` with targets on the diagonal.

    Parameters
    ----------
    m, t : (B, D) float tensors (unit rows).
    text_index : (B,) int tensor, identifies equal texts.
    temperature : float τ > 0.

    Returns
    -------
    scalar tensor.
    """
    B = m.shape[0]
    logits = m @ t.T / temperature                                            # (B, B)
    same = text_index[:, None] == text_index[None, :]
    eye = torch.eye(B, dtype=torch.bool, device=m.device)
    logits = logits.masked_fill(same & ~eye, float("-inf"))
    target = torch.arange(B, device=m.device)
    return 0.5 * (F.cross_entropy(logits, target) + F.cross_entropy(logits.T, target))


# ----------------------------------------------------------------------------- metrics


def _check_emb(E, name, min_rows=1):
    E = np.asarray(E)
    if E.dtype == object or not np.issubdtype(E.dtype, np.number):
        raise ValueError(f"{name} must be a numeric (N, D) array, got dtype {E.dtype}")
    if E.ndim != 2:
        raise ValueError(f"{name} must have shape (N, D), got {E.shape}")
    if len(E) < min_rows:
        raise ValueError(f"{name} has {len(E)} rows; need at least {min_rows}")
    if not np.all(np.isfinite(E)):
        raise ValueError(f"{name} contains NaN or inf")
    return E.astype(np.float64)


def _check_pair(A, B, name_a, name_b, min_rows=1):
    A, B = _check_emb(A, name_a, min_rows), _check_emb(B, name_b, min_rows)
    if A.shape != B.shape:
        raise ValueError(f"{name_a} {A.shape} and {name_b} {B.shape} must have the same shape "
                         f"(row i of one matches row i of the other)")
    return A, B


def euclidean_distance_matrix(A, B):
    """``d_ij = |A_i - B_j|``: A (N, D), B (M, D) -> (N, M) float64."""
    A, B = _check_emb(A, "A"), _check_emb(B, "B")
    if A.shape[1] != B.shape[1]:
        raise ValueError(f"A and B need the same width D, got {A.shape} and {B.shape}")
    d2 = (A * A).sum(1)[:, None] - 2.0 * A @ B.T + (B * B).sum(1)[None, :]   # (N, M)
    return np.sqrt(np.maximum(d2, 0.0))


def fid(real_emb, gen_emb):
    """Fréchet distance between Gaussians fitted to two embedding sets (FID, Heusel et al.
    2017; Guo et al. 2022's motion FID):

    ``FID = |μ_r - μ_g|² + tr(Σ_r + Σ_g - 2 (Σ_r Σ_g)^{1/2})``

    with sample means and covariances (``ddof = 1``). ``tr (Σ_r Σ_g)^{1/2}`` is computed as
    ``Σ_k sqrt(λ_k)`` of the symmetric PSD matrix ``Σ_r^{1/2} Σ_g Σ_r^{1/2}`` (same eigenvalues
    as ``Σ_r Σ_g``), which equals the ``scipy.linalg.sqrtm(Σ_r Σ_g)`` of the reference code
    but stays real and stable when the covariances are singular (fewer samples than ``D``).

    Parameters
    ----------
    real_emb : (N_r, D) float array, N_r >= 2.
    gen_emb : (N_g, D) float array, N_g >= 2 (N_g may differ from N_r).

    Returns
    -------
    float >= 0 (0 for identical sets). With few samples the estimate is biased upwards
    (two independent sets of one distribution do not give 0): compare rows of equal ``N``.
    """
    from scipy import linalg

    R = _check_emb(real_emb, "real_emb")
    G = _check_emb(gen_emb, "gen_emb")
    for E, name in ((R, "real_emb"), (G, "gen_emb")):
        if len(E) < 2:
            raise ValueError(f"{name} has {len(E)} row(s); FID needs at least 2 samples per "
                             f"set (a covariance), better several times D = {E.shape[1]}")
    if R.shape[1] != G.shape[1]:
        raise ValueError(f"real_emb and gen_emb need the same width D, got {R.shape} and "
                         f"{G.shape}")
    mu_r, mu_g = R.mean(0), G.mean(0)
    S_r, S_g = np.cov(R, rowvar=False), np.cov(G, rowvar=False)               # (D, D)
    w, V = linalg.eigh(S_r)
    half = (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T                         # Σ_r^{1/2}
    lam = linalg.eigvalsh(half @ S_g @ half)
    tr_covmean = np.sqrt(np.clip(lam, 0.0, None)).sum()
    d = mu_r - mu_g
    return float(max(d @ d + np.trace(S_r) + np.trace(S_g) - 2.0 * tr_covmean, 0.0))


def _batches(n, batch, seed):
    order = np.arange(n) if seed is None else np.random.default_rng(seed).permutation(n)
    return [order[b * batch:(b + 1) * batch] for b in range(n // batch)]


def _check_rp_args(n, top_k, batch, texts):
    for name, v in (("top_k", top_k), ("batch", batch)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
    if top_k > batch:
        raise ValueError(f"top_k={top_k} must be <= batch={batch}")
    if n < batch:
        raise ValueError(f"R-precision ranks each motion among batch={batch} texts but only "
                         f"{n} pairs were given; give >= {batch} or a smaller batch")
    if texts is not None:
        texts = [str(t) for t in texts]
        if len(texts) != n:
            raise ValueError(f"texts has {len(texts)} entries for {n} embedding pairs")
    return texts


def r_precision(text_emb, motion_emb, top_k=3, batch=32, texts=None, seed=None):
    """R-precision (Guo et al. 2022): how often a motion's own text is among the ``k``
    texts nearest to it.

    The pairs are cut into batches of ``batch`` (an incomplete last batch is dropped, as
    the reference code's ``drop_last``); in each batch every motion ranks the batch's texts
    by Euclidean distance. **Duplicates**: with ``texts`` given, equal texts of a batch are
    one candidate (a motion of "a person walks" is not penalised for another window's
    identical "a person walks" being nearer), so a batch with ``U`` distinct texts ranks
    ``U`` candidates and chance is ``k / U`` (:func:`r_precision_chance`). Without
    ``texts`` each row is its own candidate and ties (equal text embeddings) count in
    the motion's favour. The reference code ranks motions per text; this ranks texts per
    motion, as the paper describes it.

    Parameters
    ----------
    text_emb, motion_emb : (N, D) float arrays, row i of each is a matched pair.
    top_k : int >= 1.
    batch : int >= top_k, candidates per ranking (32 in the benchmark).
    texts : None or list of N str (the texts of the rows).
    seed : None (batches in the given order) or int (rows shuffled by
        ``np.random.default_rng(seed)`` first, as the reference's shuffled loader).

    Returns
    -------
    (top_k,) float array: entry ``k - 1`` is the top-k precision (cumulative), over the
    ``batch * (N // batch)`` motions in complete batches.
    """
    Tt, M = _check_pair(text_emb, motion_emb, "text_emb", "motion_emb")
    texts = _check_rp_args(len(M), top_k, batch, texts)
    hits = []
    for idx in _batches(len(M), batch, seed):
        if texts is None:
            own = np.arange(len(idx))                                         # (B,)
            cand = Tt[idx]                                                    # (B, D)
        else:
            labels = [texts[i] for i in idx]
            uniq, first, own = np.unique(labels, return_index=True, return_inverse=True)
            cand = Tt[idx[first]]                                             # (U, D)
        d = euclidean_distance_matrix(M[idx], cand)                           # (B, U)
        d_own = d[np.arange(len(idx)), own]
        rank = (d < d_own[:, None]).sum(1)                                    # (B,) 0 = best
        hits.append(rank[:, None] < np.arange(1, top_k + 1)[None, :])         # (B, k)
    return np.concatenate(hits).mean(0)


def r_precision_chance(n, top_k=3, batch=32, texts=None, seed=None):
    """Expected :func:`r_precision` of embeddings that carry no information, for the same
    batches: ``mean over motions of min(k, U) / U`` with ``U`` the number of candidates of
    the motion's batch (``batch``, or the distinct texts of the batch when ``texts`` is
    given). n : int, number of pairs. Returns a (top_k,) float array."""
    texts = _check_rp_args(int(n), top_k, batch, texts)
    out = []
    for idx in _batches(int(n), batch, seed):
        U = len(idx) if texts is None else len({texts[i] for i in idx})
        out.append(np.repeat(np.minimum(np.arange(1, top_k + 1), U)[None] / U, len(idx), 0))
    return np.concatenate(out).mean(0)


def mm_dist(text_emb, motion_emb):
    """Multimodal distance (Guo et al. 2022's "MM-Dist", the reference code's matching
    score): mean Euclidean distance between matched text and motion embeddings,
    ``(1/N) Σ_i |t_i - m_i|``. text_emb, motion_emb : (N, D). Returns a float."""
    Tt, M = _check_pair(text_emb, motion_emb, "text_emb", "motion_emb")
    return float(np.linalg.norm(Tt - M, axis=1).mean())


def diversity(emb, n_pairs=300, seed=0):
    """Diversity (Guo et al. 2022): mean Euclidean distance between random pairs of
    embeddings.

    Parameters
    ----------
    emb : (N, D) float array.
    n_pairs : int or None. An int draws two index sets of ``n_pairs`` without replacement
        (the reference code; needs ``N > n_pairs``; 300 in the benchmark) and averages
        ``|e_a - e_b|`` over the paired draws. None averages over all ``N (N - 1) / 2``
        pairs of distinct rows — the expectation the sampled version estimates, without its
        sampling noise; use it for small sets.
    seed : int, seeds the draws.

    Returns
    -------
    float.
    """
    E = _check_emb(emb, "emb", min_rows=2)
    N = len(E)
    if n_pairs is None:
        i, j = np.triu_indices(N, k=1)
        return float(np.linalg.norm(E[i] - E[j], axis=1).mean())
    if isinstance(n_pairs, bool) or not isinstance(n_pairs, (int, np.integer)) or n_pairs < 1:
        raise ValueError(f"n_pairs must be an integer >= 1 or None, got {n_pairs!r}")
    if N <= n_pairs:
        raise ValueError(f"diversity with n_pairs={n_pairs} needs more than {n_pairs} "
                         f"embeddings, got {N}; use n_pairs=None (all pairs) for small sets")
    rng = np.random.default_rng(seed)
    a = rng.choice(N, n_pairs, replace=False)
    b = rng.choice(N, n_pairs, replace=False)
    return float(np.linalg.norm(E[a] - E[b], axis=1).mean())


def evaluate_embeddings(real_emb, gen_emb, text_emb, texts=None, top_k=3, batch=32,
                        diversity_pairs=300, seed=0):
    """The four metrics of a generated set.

    Parameters
    ----------
    real_emb : (N_r, D) float array, embeddings of the real reference motions (FID).
    gen_emb : (N, D) float array, embeddings of the motions scored.
    text_emb : (N, D) float array, embeddings of their texts (row i of ``gen_emb``).
    texts : None or list of N str, the texts (duplicates are one R-precision candidate).
    top_k, batch : R-precision settings (:func:`r_precision`); batch is lowered to ``N``
        when fewer pairs are given.
    diversity_pairs : int; the reference's sampled pairs if ``N > diversity_pairs``, else
        all pairs (:func:`diversity` with None).
    seed : int, shuffles the R-precision batches and seeds the diversity draws.

    Returns
    -------
    dict: ``fid``, ``r_precision_top1`` .. ``r_precision_top{k}``, ``r_precision_chance_top{k}``,
    ``mm_dist``, ``diversity`` (floats) and ``n`` (int).
    """
    G = _check_emb(gen_emb, "gen_emb", min_rows=2)
    Tt = _check_emb(text_emb, "text_emb")
    if Tt.shape != G.shape:
        raise ValueError(f"text_emb {Tt.shape} must have the shape of gen_emb {G.shape}")
    n = len(G)
    batch = min(int(batch), n)
    rp = r_precision(Tt, G, top_k=top_k, batch=batch, texts=texts, seed=seed)
    chance = r_precision_chance(n, top_k=top_k, batch=batch, texts=texts, seed=seed)
    out = {"fid": fid(real_emb, G)}
    out.update({f"r_precision_top{k + 1}": float(v) for k, v in enumerate(rp)})
    out.update({f"r_precision_chance_top{k + 1}": float(v) for k, v in enumerate(chance)})
    out["mm_dist"] = mm_dist(Tt, G)
    out["diversity"] = diversity(G, diversity_pairs if n > diversity_pairs else None, seed)
    out["n"] = n
    return out


# ----------------------------------------------------------------------------- evaluator


def _train_command(path):
    return (f"`python -m physlab.motion.evaluator train --out runs/motion/evaluator.pt "
            f"--export {path}` (add --smoke for a seconds-long test model)")


class TextMotionEvaluator:
    """A trained text–motion evaluator: encoders + normalisation + text cache.

    Parameters
    ----------
    model : :class:`TextMotionModel` (eval mode).
    mean, std : (69,) float arrays, feature normalisation.
    text_cache : :class:`~physlab.motion.text.EmbeddingCache` of MiniLM embeddings.
    path : Path or None, where it was loaded from.

    Attributes
    ----------
    config : :class:`EvaluatorConfig`; embed_dim : int D; n_frames : int (40);
    train_takes : tuple of str, the Bandai-Namco takes it was trained on.
    """

    def __init__(self, model, mean, std, text_cache, path=None, train_takes=()):
        self.model = model.eval()
        self.config = model.config
        self.mean = torch.as_tensor(np.asarray(mean, dtype=np.float32))
        self.std = torch.as_tensor(np.asarray(std, dtype=np.float32))
        self.text_cache = text_cache
        self.path = path
        self.train_takes = tuple(train_takes)

    def __repr__(self):
        return (f"TextMotionEvaluator(path={str(self.path)!r}, D={self.embed_dim}, "
                f"{len(self.text_cache)} cached texts)")

    @property
    def embed_dim(self):
        return self.config.embed_dim

    @property
    def n_frames(self):
        return self.config.n_frames

    @classmethod
    def from_checkpoint(cls, path=DEFAULT_EVALUATOR):
        """Load an evaluator checkpoint (:func:`train`'s output or its fp16 export).

        Loading never runs code from the file
        (:func:`~physlab.motion.checkpoint.load_checkpoint`, ``weights_only=True``).
        FileNotFoundError with the training command if missing; ValueError if the file is
        corrupt, unsafe, or not an evaluator checkpoint."""
        from .text import EmbeddingCache, hash_encoder

        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no text-motion evaluator at {path}; make one with "
                                    f"{_train_command(path)}")
        ckpt = load_checkpoint(path)
        if ckpt.get("stage") != STAGE:
            raise ValueError(f"{path} is a '{ckpt.get('stage')}' checkpoint of the motion "
                             f"generator, not a text-motion evaluator; give "
                             f"{DEFAULT_EVALUATOR.name} or train one with "
                             f"{_train_command(path)}")
        missing = sorted({"model_config", "motion_stats", "text_cache"} - set(ckpt))
        if missing:
            raise ValueError(f"{path} lacks {missing}; retrain with {_train_command(path)}")
        model = TextMotionModel(EvaluatorConfig.from_dict(ckpt["model_config"]))
        try:
            model.load_state_dict({k: v.float() for k, v in ckpt["model"].items()})
        except RuntimeError as e:
            raise ValueError(f"{path}: the weights do not fit the saved model config "
                             f"({' '.join(str(e).split())[:200]}); retrain with "
                             f"{_train_command(path)}") from None
        encoder = hash_encoder if (ckpt.get("train_config") or {}).get(
            "text_encoder") == "hash" else None
        cache = EmbeddingCache.from_state_dict(ckpt["text_cache"], encoder=encoder)
        stats = ckpt["motion_stats"]
        return cls(model, stats["mean"], stats["std"], cache, path=path,
                   train_takes=ckpt.get("train_takes") or ())

    @torch.no_grad()
    def encode_motion(self, joints, batch_size=512):
        """Embed windows.

        Parameters
        ----------
        joints : (N, 40, 22, 3) float array, canonical windows (m, y up, 20 fps; frame-0
            pelvis at ``x = z = 0`` facing ``+z``, as :func:`~physlab.motion.dataset.
            make_windows` and the generator produce). ValueError for another shape, NaN/inf.
        batch_size : int >= 1, windows per forward pass.

        Returns
        -------
        (N, D) float32 array of unit vectors.
        """
        x = _check_motion(joints, "joints", self.n_frames)
        out = []
        for s in range(0, len(x), int(batch_size)):
            f = (motion_features(x[s:s + int(batch_size)]) - self.mean) / self.std  # (b, T, F)
            out.append(self.model.motion(f))                                  # (b, D)
        return torch.cat(out).numpy()

    @torch.no_grad()
    def encode_text(self, texts):
        """Embed texts: list of N str -> (N, D) float32 unit vectors. Known texts come from
        the stored MiniLM embeddings; unknown ones load the sentence encoder
        (:class:`~physlab.motion.text.ActionEncoder`) once."""
        if isinstance(texts, str):
            raise ValueError(f"texts must be a list of str, got a single str {texts!r}; "
                             f"wrap it: [text]")
        texts = list(texts)
        if not texts:
            raise ValueError("texts is empty; give at least one text")
        a = torch.as_tensor(self.text_cache.get(texts), dtype=torch.float32)   # (N, 384)
        return self.model.text(a).numpy()                                     # (N, D)

    def evaluate(self, real_joints, gen_joints, texts, top_k=3, batch=32,
                 diversity_pairs=300, seed=0):
        """FID (``gen_joints`` against ``real_joints``), R-precision, MM-Dist and Diversity
        of ``gen_joints`` with their ``texts`` (:func:`evaluate_embeddings`).

        Parameters
        ----------
        real_joints : (N_r, 40, 22, 3) float array, the real reference windows (N_r >= 2).
        gen_joints : (N, 40, 22, 3) float array, the windows scored (N >= 2).
        texts : list of N str, the text of each scored window.

        Returns
        -------
        dict of :func:`evaluate_embeddings`.
        """
        R = _check_motion(real_joints, "real_joints", self.n_frames)
        G = _check_motion(gen_joints, "gen_joints", self.n_frames)
        texts = [texts] if isinstance(texts, str) else list(texts)
        if len(texts) != len(G):
            raise ValueError(f"texts must be a list with one str per window of gen_joints "
                             f"({len(G)}), got {len(texts)}")
        R, G = self.encode_motion(R), self.encode_motion(G)
        return evaluate_embeddings(R, G, self.encode_text(texts), texts=texts, top_k=top_k,
                                   batch=batch, diversity_pairs=diversity_pairs, seed=seed)


# ----------------------------------------------------------------------------- training


def _training_windows(cfg):
    """Canonical 40-frame windows of the training clips (every take but 002)."""
    root = cfg.data_root or None
    if cfg.max_clips:
        rows = [r for r in read_labels(root) if r["take"] not in TEST_TAKES]
        clips = load_clips(root, clip_ids=[Path(r["file"]).stem for r in rows[:cfg.max_clips]])
    else:
        clips, _ = split_by_take(load_clips(root, progress=cfg.progress))
    return make_windows(clips, length=40, stride=cfg.window_stride), clips


def _text_cache(texts, cfg, cache=None):
    """An EmbeddingCache holding ``texts`` (and, for MiniLM, the whole training vocabulary)."""
    from .text import ActionEncoder, EmbeddingCache, hash_encoder, training_vocabulary

    if cache is None:
        if cfg.text_cache and Path(cfg.text_cache).is_file():
            cache = EmbeddingCache.load(cfg.text_cache)
        else:
            cache = EmbeddingCache()
    want = list(dict.fromkeys(list(texts) + (training_vocabulary(styles=True)
                                             if cfg.text_encoder == "minilm" else [])))
    if any(t not in cache for t in want):
        encoder = (hash_encoder if cfg.text_encoder == "hash"
                   else ActionEncoder(num_threads=cfg.num_threads))
        cache.get(sorted(set(want)), encoder=encoder)
        if cfg.text_cache:
            cache.save(cfg.text_cache)
    return cache


def _rng_state(g):
    return {"torch": torch.get_rng_state(), "gen": g.get_state()}


def _feature_stats(joints, mirror):
    """Mean and std (floored at 1e-3) of :func:`motion_features` over all frames of the
    windows (and of their mirror images): two (69,) float32 arrays."""
    s, s2, n = 0.0, 0.0, 0
    for x in ([joints, mirror_joints(joints)] if mirror else [joints]):
        for c in range(0, len(x), 1024):
            f = motion_features(x[c:c + 1024]).double().reshape(-1, FEATURE_DIM)
            s, s2, n = s + f.sum(0), s2 + (f * f).sum(0), n + len(f)
    mean = s / n
    std = torch.sqrt(torch.clamp(s2 / n - mean * mean, min=0.0)).clamp(min=1e-3)
    return mean.float().numpy(), std.float().numpy()


def train(**kwargs):
    """Train (or resume) the text–motion evaluator; keyword names = the CLI flags
    (fields of :class:`EvaluatorTrainConfig` and :class:`EvaluatorConfig`).

    Data: the Bandai-Namco training clips (every take but the held-out 002), 40-frame
    windows (stride ``window_stride``), texts :func:`~physlab.motion.dataset.action_text`.
    Each step draws ``batch_size`` windows uniformly (``torch.Generator`` seeded by
    ``seed``), mirrors half of them (:func:`mirror_joints`, :func:`mirror_text`), and takes
    one AdamW step on :func:`info_nce`. A checkpoint (model, optimizer, step, RNG states,
    feature statistics, MiniLM text cache, configs, ``train_takes``) is written atomically
    every ``checkpoint_every`` steps, at the end, and on Ctrl-C; rerunning the command
    resumes from it, and with one thread a resumed run equals an uninterrupted one.

    Returns
    -------
    dict: ``path``, ``step``, ``trained`` (steps this call ran; 0 when the checkpoint had
    ``steps`` already), ``loss`` (last step; the checkpoint's when nothing was trained),
    ``seconds`` (this call's training time), ``n_params``, ``export`` (Path or None).
    """
    from tqdm.auto import tqdm

    t_fields = {f.name for f in dataclasses.fields(EvaluatorTrainConfig)}
    m_fields = {f.name for f in dataclasses.fields(EvaluatorConfig)}
    unknown = sorted(set(kwargs) - t_fields - m_fields)
    if unknown:
        raise ValueError(f"unknown options {unknown}; see `python -m physlab.motion.evaluator "
                         f"train -h`")
    tk = {k: v for k, v in kwargs.items() if k in t_fields}
    mk = {k: v for k, v in kwargs.items() if k in m_fields}
    if tk.get("smoke"):
        tk = {"steps": 4, "batch_size": 16, "max_clips": 4, "text_encoder": "hash",
              "checkpoint_every": 2, "warmup": 1, **tk}
        mk = {**SMOKE_MODEL, **mk}
    cfg = EvaluatorTrainConfig(**tk)
    if int(os.environ.get("WORLD_SIZE", "1")) > 1:
        raise ValueError("the evaluator trains in one process (~10 min on one core); run "
                         "`python -m physlab.motion.evaluator train ...` without torchrun")
    torch.set_num_threads(cfg.num_threads)
    out = Path(cfg.out)

    resume = None
    if cfg.resume and out.is_file():
        resume = load_checkpoint(out)
        if resume.get("stage") != STAGE:
            raise ValueError(f"{out} holds a '{resume.get('stage')}' checkpoint, not an "
                             f"evaluator's; use another --out")
        if "optimizer" not in resume:
            raise ValueError(f"{out} is an inference-only export (no optimizer state); "
                             f"resume from the full checkpoint or use another --out")
        model_cfg = EvaluatorConfig.from_dict(resume["model_config"])
        if mk:
            print(f"note: model options {sorted(mk)} ignored; the model config comes from "
                  f"{out}", file=sys.stderr)
    else:
        model_cfg = EvaluatorConfig(**mk)

    torch.manual_seed(cfg.seed)
    g = torch.Generator().manual_seed(cfg.seed + 1000)
    win, clips = _training_windows(cfg)
    if model_cfg.n_frames != win.length:
        raise ValueError(f"model n_frames={model_cfg.n_frames} but windows have {win.length}")
    texts = sorted(set(win.text) | {mirror_text(t) for t in win.text})
    from .text import EmbeddingCache
    cache = _text_cache(texts, cfg, None if resume is None else
                        EmbeddingCache.from_state_dict(resume["text_cache"]))
    index = {t: i for i, t in enumerate(texts)}
    text_idx = torch.tensor([index[t] for t in win.text])                     # (N,)
    mirror_idx = torch.tensor([index[mirror_text(t)] for t in win.text])      # (N,)
    text_emb = torch.as_tensor(cache.get(texts), dtype=torch.float32)         # (V, 384)
    joints = torch.as_tensor(win.joints, dtype=torch.float32)                 # (N, 40, 22, 3)
    if resume is None:
        mean, std = _feature_stats(joints, cfg.mirror)
    else:
        mean, std = (np.asarray(resume["motion_stats"][k], np.float32) for k in ("mean", "std"))
    mean_t, std_t = torch.as_tensor(mean), torch.as_tensor(std)

    model = TextMotionModel(model_cfg)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    step = 0
    if resume is not None:
        model.load_state_dict(resume["model"])
        opt.load_state_dict(resume["optimizer"])
        step = int(resume["step"])
        torch.set_rng_state(resume["rng"]["torch"])
        g.set_state(resume["rng"]["gen"])
    model.train()
    takes = sorted({c.take for c in clips})
    N, B = len(joints), cfg.batch_size
    n_params = sum(p.numel() for p in model.parameters())

    def checkpoint(loss):
        save_checkpoint(out, {
            "kind": CHECKPOINT_KIND, "version": CHECKPOINT_VERSION, "stage": STAGE,
            "model_config": model_cfg.to_dict(), "train_config": dataclasses.asdict(cfg),
            "model": model.state_dict(), "optimizer": opt.state_dict(), "step": step,
            "rng": _rng_state(g), "motion_stats": {"mean": mean, "std": std},
            "text_cache": cache.state_dict(), "loss": loss, "train_takes": takes,
            "n_windows": N, "attribution": BANDAI_NAMCO_ATTRIBUTION})

    bar = tqdm(total=cfg.steps, initial=step, disable=not cfg.progress, desc="train evaluator")
    loss_v = float(resume.get("loss", float("nan"))) if resume is not None else float("nan")
    tic, first_step = time.perf_counter(), step
    try:
        while step < cfg.steps:
            for group in opt.param_groups:
                group["lr"] = warmup_cosine_lr(cfg, step)
            idx = torch.randint(N, (B,), generator=g)                         # (B,)
            x = joints[idx]                                                   # (B, 40, 22, 3)
            ti = text_idx[idx]
            if cfg.mirror:
                flip = torch.rand(B, generator=g) < 0.5                       # (B,)
                x = torch.where(flip[:, None, None, None], mirror_joints(x), x)
                ti = torch.where(flip, mirror_idx[idx], ti)
            f = (motion_features(x) - mean_t) / std_t                         # (B, 40, 69)
            m, t = model(f, text_emb[ti])                                     # (B, D) each
            loss = info_nce(m, t, ti, cfg.temperature)
            if not torch.isfinite(loss):
                raise FloatingPointError(f"loss became {loss.item()} at step {step}; lower "
                                         f"--lr or raise --temperature")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            if cfg.grad_clip > 0:
                torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            opt.step()
            step += 1
            loss_v = loss.item()
            bar.update(1)
            bar.set_postfix(loss=f"{loss_v:.3f}")
            if step % cfg.checkpoint_every == 0 or step == cfg.steps:
                checkpoint(loss_v)
    except KeyboardInterrupt:
        bar.close()
        if step > 0:
            checkpoint(loss_v)
            print(f"interrupted: checkpoint of step {step} written to {out}", file=sys.stderr)
        raise
    bar.close()
    seconds = time.perf_counter() - tic
    if not out.is_file():                       # nothing trained and nothing to resume
        checkpoint(loss_v)
    exported = export_weights(out, cfg.export) if cfg.export else None
    return {"path": out, "step": step, "trained": step - first_step, "loss": loss_v,
            "seconds": seconds, "n_params": n_params, "export": exported}


# ----------------------------------------------------------------------------- sanity check


def held_out_data(data_root=None, stride=10):
    """All held-out (take 002) windows: dict ``joints`` (M, 40, 22, 3), ``text`` (M str),
    ``clip_id`` (M str). The same windows as :func:`physlab.motion.evaluate.held_out_windows`
    draws from (stride 10)."""
    ids = [Path(r["file"]).stem for r in read_labels(data_root) if r["take"] in TEST_TAKES]
    _, test = split_by_take(load_clips(data_root, clip_ids=ids))
    win = make_windows(test, length=40, stride=stride)
    return {"joints": win.joints, "text": list(win.text), "clip_id": list(win.clip_id)}


def sanity_report(evaluator=None, data_root=None, windows=64, seed=0, noise=0.05):
    """What the evaluator says about real held-out motion, and about broken motion.

    On the ``M`` held-out take-002 windows (:func:`held_out_data`):

    * ``all``: R-precision top-1..3 (batches of 32, duplicate texts merged), its chance
      level, MM-Dist and Diversity (300 pairs) of all ``M`` windows;
    * ``fid_halves``: FID between the first and the second half of every held-out clip's
      windows (real vs real, ~M/2 each, the same texts in both);
    * ``fid_train``: FID of all held-out windows against 2000 training windows (a new take
      of the same actions);
    * ``subset``: the :func:`evaluate_embeddings` row of ``windows`` evenly spaced windows
      (as ``physlab.motion.evaluate`` picks them) against the other ``M - windows`` as the
      real reference, and the same for three broken versions of those windows: ``noised``
      (Gaussian noise of ``noise`` m on every joint and frame), ``frozen`` (frame 0
      repeated), ``shuffled texts`` (texts permuted).

    Returns
    -------
    dict of floats / dicts (see :func:`format_report`).
    """
    ev = evaluator if evaluator is not None else TextMotionEvaluator.from_checkpoint()
    data = held_out_data(data_root)
    X, texts, clip = data["joints"], data["text"], np.asarray(data["clip_id"])
    M = len(X)
    E = ev.encode_motion(X)
    T = ev.encode_text(texts)
    rep = {"n_held_out": M, "all": evaluate_embeddings(E, E, T, texts=texts, seed=seed)}
    rep["all"].pop("fid")
    first = np.zeros(M, dtype=bool)                   # first half of each clip's windows
    for c in set(clip):
        w = np.flatnonzero(clip == c)
        first[w[:len(w) // 2]] = True
    rep["fid_halves"] = fid(E[first], E[~first])
    win, _ = _training_windows(EvaluatorTrainConfig(data_root=data_root or "",
                                                    progress=False))
    pick = np.random.default_rng(seed).choice(len(win), min(2000, len(win)), replace=False)
    rep["fid_train"] = fid(ev.encode_motion(win.joints[pick]), E)

    idx = np.round(np.linspace(0, M - 1, windows)).astype(int)
    rest = np.setdiff1d(np.arange(M), idx)
    sub, sub_texts = X[idx], [texts[i] for i in idx]
    rng = np.random.default_rng(seed)
    broken = {"real": (sub, sub_texts),
              "noised": (sub + noise * rng.standard_normal(sub.shape), sub_texts),
              "frozen": (np.repeat(sub[:, :1], sub.shape[1], axis=1), sub_texts),
              "shuffled texts": (sub, [sub_texts[i] for i in rng.permutation(len(idx))])}
    rep["subset"] = {name: evaluate_embeddings(E[rest], ev.encode_motion(x),
                                               ev.encode_text(t), texts=t, seed=seed)
                     for name, (x, t) in broken.items()}
    rep["windows"], rep["noise_m"] = int(windows), float(noise)
    return rep


def format_report(rep):
    """Markdown of :func:`sanity_report`."""
    a = rep["all"]
    lines = [f"All {rep['n_held_out']} held-out windows (take {', '.join(TEST_TAKES)}): "
             f"R-precision top-1/2/3 {a['r_precision_top1']:.3f} / {a['r_precision_top2']:.3f}"
             f" / {a['r_precision_top3']:.3f} (chance {a['r_precision_chance_top1']:.3f} / "
             f"{a['r_precision_chance_top2']:.3f} / {a['r_precision_chance_top3']:.3f}), "
             f"MM-Dist {a['mm_dist']:.3f}, Diversity {a['diversity']:.3f}.",
             f"FID real vs real (first vs second half of each held-out clip): "
             f"{rep['fid_halves']:.4f}; "
             f"held-out vs training windows: {rep['fid_train']:.4f}.", "",
             f"{rep['windows']} evenly spaced held-out windows against the other "
             f"{rep['n_held_out'] - rep['windows']} as reference:", "",
             "| set | FID ↓ | R-prec. top-1 ↑ | top-2 ↑ | top-3 ↑ | chance top-3 "
             "| MM-Dist ↓ | Diversity |", "|---|---|---|---|---|---|---|---|"]
    for name, r in rep["subset"].items():
        label = f"noised ({rep['noise_m'] * 100:g} cm)" if name == "noised" else name
        lines.append(f"| {label} | {r['fid']:.4f} | {r['r_precision_top1']:.3f} | "
                     f"{r['r_precision_top2']:.3f} | {r['r_precision_top3']:.3f} | "
                     f"{r['r_precision_chance_top3']:.3f} | {r['mm_dist']:.3f} | "
                     f"{r['diversity']:.3f} |")
    lines += ["", f"Data: {BANDAI_NAMCO_ATTRIBUTION}"]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- CLI


def _parser():
    from physlab._cli import Parser

    p = Parser(prog="python -m physlab.motion.evaluator",
               description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="train (or resume) the evaluator")
    for cls in (EvaluatorTrainConfig, EvaluatorConfig):
        group = t.add_argument_group(cls.__name__)
        for f in dataclasses.fields(cls):
            flag = "--" + f.name.replace("_", "-")
            if f.type in ("bool", bool):
                group.add_argument(flag, action=argparse.BooleanOptionalAction, default=None)
            else:
                typ = {"int": int, "float": float, "str": str}.get(f.type, f.type)
                group.add_argument(flag, type=typ, default=None, help=f"default {f.default!r}")
    c = sub.add_parser("check", help="metrics of real held-out windows (sanity)")
    c.add_argument("--checkpoint", default=str(DEFAULT_EVALUATOR),
                   help="evaluator checkpoint (default: the shipped one)")
    c.add_argument("--windows", type=int, default=64,
                   help="evenly spaced held-out windows of the subset table (default 64)")
    c.add_argument("--data-root", default=None, help="Bandai-Namco folder (labels.csv)")
    c.add_argument("--seed", type=int, default=0)
    return p


def main(argv=None):
    """Command-line entry point (``train`` / ``check``); returns the result dict."""
    args = vars(_parser().parse_args(argv))
    args.pop("debug", None)
    command = args.pop("command")
    if command == "check":
        torch.set_num_threads(1)
        rep = sanity_report(TextMotionEvaluator.from_checkpoint(args["checkpoint"]),
                            data_root=args["data_root"], windows=args["windows"],
                            seed=args["seed"])
        print(format_report(rep))
        return rep
    from physlab._cli import stop_like_ctrl_c

    stop_like_ctrl_c()                  # `kill PID` / Ctrl-C: checkpoint, then resume later
    res = train(**{k: v for k, v in args.items() if v is not None})
    took = f"{res['seconds']:.0f} s" if res["trained"] else NOTHING_LEFT_TO_TRAIN
    print(f"evaluator: step {res['step']}, loss {res['loss']:.4f}, {took}, "
          f"{res['n_params']:,} parameters -> {res['path']}")
    if res["export"] is not None:
        print(f"inference weights (fp16, {res['export'].stat().st_size / 2**20:.1f} MiB) -> "
              f"{res['export']}")
    return res


if __name__ == "__main__":
    from physlab._cli import guard

    sys.exit(guard("python -m physlab.motion.evaluator", main))
