"""The Sketch2Anim motion generator: a text-conditioned denoiser, the trajectory ControlNet and
the trajectory-aware keypose adapter (Sketch2Anim Sec. 4, Eqs. (1)–(4)).

Design (and where it departs from the paper)
-------------------------------------------
* **Motion features, no VAE.** Sketch2Anim builds on MLD, whose denoiser works in the latent
  space of a motion VAE. Here the denoiser works on the normalised
  :mod:`~physlab.motion.features` rows directly (``x_t`` plays the role of ``z_t``): it is
  simpler (one network, one training stage less), the decoder ``R(.)`` of Eqs. (6) and (8)
  is the *exact* analytic inverse :func:`features_to_joints_torch` instead of a learned
  decoder, and with ~2 k training windows a VAE would have little data to learn a good latent
  space from.
* **Frames vs. rows.** A window of ``N = 40`` joint frames has ``n_frames = 39`` feature rows
  (row ``i`` is made from frames ``i`` and ``i + 1``); :func:`features_to_joints_torch`
  returns all 40 frames (the last from the last row's joint velocities). Conditions live on
  the 40 frames (:mod:`~physlab.motion.dataset`); :class:`FrameConditionEncoder` maps them to
  the 39 rows by encoding the frames and mixing frames ``i`` and ``i + 1`` into row ``i``.
* **Denoiser** ``eps_theta(x_t, t, a)``: a pre-LayerNorm transformer encoder over
  ``1 + n_frames`` tokens: one condition token ``time_mlp(sinusoid(t)) + text_proj(a)`` (MLD
  supp.: text embedding added to the time embedding and concatenated with the latent),
  followed by the motion rows ``motion_in(x_t) + pos``. The output is what the scheduler's
  ``prediction_type`` says: x₀ by default, ε as in the paper (see
  :mod:`physlab.motion.train` for why). Classifier-free
  guidance (Eq. (14)): ``drop_text`` replaces ``a`` by a learned null embedding.
* **ControlNet residuals** are added to the token stream after every block
  (``h_i <- block_i(h_{i-1}) + r_i``), as MLD/OmniControl-style ControlNets do.
* **Trajectory ControlNet** (Eq. (1)): a trainable copy of the denoiser's encoder (input
  layers + blocks, initialised from the base weights) whose motion tokens get
  ``E_tr(T)`` added — ``z'_t = z_t + E_tr(T)`` written in token space (adding a 137-d
  embedding before the linear ``motion_in`` is the special case ``W E``). Each block output goes through
  a zero-initialised linear layer ``Z_i``: residuals ``r_i``.
* **Keypose adapter** (Eqs. (2)–(4)): another trainable copy whose condition token carries
  the grounded action embedding ``a' = a + E_k(K)`` (Eq. (2), in token space), whose blocks
  receive the ControlNet residuals ``r_i`` (``h_i <- block_i(h_{i-1}) + r_i``, Eq. (3)) and
  whose zero-initialised outputs ``r'_i = Z'_i(h_i)`` are added to the frozen base denoiser
  (Eq. (4)). Before training, :class:`ControlledDenoiser` therefore returns exactly the base
  denoiser's output.
* **Single ControlNet** (Table 2 ablation): ``single_controlnet=True`` puts the keypose into
  its frame of a unified per-frame condition matrix, one ControlNet encodes it and its
  residuals go straight into the base.

* **Fused inference** (not in the paper): :class:`FusedControlledDenoiser` runs the blocks of
  one depth of the ControlNet copy, the adapter copy and the base as one batched computation
  (:class:`StackedBlocks`, ``S`` stacked encoders); the sampler uses it.

Condition encoders are constructor arguments (any module with the same call signature), so
a later 2D variant (``E^2D_tr``, ``E^2D_k``, Sec. 5) can replace the 3D ones.

Shapes: ``B`` batch, ``T = n_frames`` feature rows (39), ``N = T + 1`` frames (40),
``D = feature_dim`` (137), ``C = d_model``, ``J = 22`` joints, ``R = 6`` trajectory joints,
``S`` encoders stacked by :class:`StackedBlocks`.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from .dataset import TRAJECTORY_JOINTS
from .features import (
    ABS_BODY,
    ABS_FEATURE_DIM,
    ABS_PELVIS,
    FEATURE_DIM,
    LOCAL_VEL,
    N_JOINTS,
    REPRESENTATIONS,
    RIC,
    ROOT_ANG_VEL,
    ROOT_HEIGHT,
    ROOT_LIN_VEL,
    check_representation,
)

__all__ = [
    "ControlledDenoiser",
    "DenoiserConfig",
    "FrameConditionEncoder",
    "FusedControlledDenoiser",
    "KeyposeAdapter",
    "KeyposeEncoder",
    "MotionDenoiser",
    "SketchKeyposeEncoder",
    "StackedBlocks",
    "camera_features",
    "sketch_trajectory_encoder",
    "sketch_trajectory_frames",
    "TrajectoryControlNet",
    "CONTROLNET_VARIANTS",
    "check_condition",
    "controlnet_variant",
    "controlnet_variant_label",
    "count_parameters",
    "features_to_joints_torch",
    "low_pass_matrix",
    "timestep_embedding",
]

N_TRAJ = len(TRAJECTORY_JOINTS)


@dataclass
class DenoiserConfig:
    """Everything needed to rebuild the networks; saved in every checkpoint.

    Default size (measured on 2 CPU cores, batch 64): base 916 k parameters (3.7 MB fp32),
    ~400–450 windows/s; base + ControlNet + adapter 3.31 M parameters (2.39 M trainable),
    ~145 windows/s. ``d_model=256`` would be ~2.5x slower in the base stage and ~10x in the
    control stage.
    """

    feature_dim: int = FEATURE_DIM  # D: feature columns per row (features.FEATURE_DIM)
    n_frames: int = 39              # T: feature rows = 40 joint frames - 1 (Sketch2Anim N=40)
    d_model: int = 128              # C: token width (256: ~2.5x slower base, ~10x control)
    n_heads: int = 4                # attention heads (C must be divisible by it)
    n_layers: int = 4               # encoder blocks (Sketch2Anim supp. E: 4 in ControlNet/adapter)
    ff: int = 512                   # hidden width of each block's MLP
    dropout: float = 0.1            # dropout in attention / MLP / embeddings
    text_dim: int = 384             # width of the action embedding a (MiniLM, text.EMBED_DIM)
    cond_drop_prob: float = 0.1     # p(text -> null) in training, for CFG (Sketch2Anim Eq. 14)
    max_timesteps: int = 1000       # diffusion steps T_diff the time embedding is built for
    cond_layers: int = 1            # transformer layers in each condition encoder (supp. E: 1)
    representation: str = "relative"  # features.REPRESENTATIONS: "relative" (HumanML3D-style,
                                    # T = N - 1 rows of 137) | "absolute" (T = N rows of 70)
    smooth_basis: int = 0           # K > 0: the output keeps its K lowest DCT frequencies over
                                    # the T rows (low_pass_matrix); 0 = off. x0-prediction only
    skip: bool = False              # x̂₀ = √ᾱ_t x_t + √(1 − ᾱ_t) F: the network adds only what
                                    # x_t does not say (MotionDenoiser doc); x0-prediction only
    skip_pelvis: bool = True        # with skip: also on the pelvis position columns; False:
                                    # those stay plain x₀ ("absolute" features only)

    def __post_init__(self):
        check_representation(self.representation)
        for name in ("skip", "skip_pelvis"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"DenoiserConfig.{name} must be True or False, got "
                                 f"{getattr(self, name)!r}")
        if self.skip and not self.skip_pelvis and self.representation != "absolute":
            raise ValueError(f"DenoiserConfig.skip_pelvis=False needs representation "
                             f"'absolute' (its pelvis position columns), got "
                             f"{self.representation!r}")
        if (isinstance(self.smooth_basis, bool) or not isinstance(self.smooth_basis, int)
                or not 0 <= self.smooth_basis <= self.n_frames):
            raise ValueError(f"DenoiserConfig.smooth_basis must be an integer in 0..n_frames "
                             f"({self.n_frames}), got {self.smooth_basis!r}")
        for name in ("feature_dim", "n_frames", "d_model", "n_heads", "n_layers", "ff",
                     "text_dim", "max_timesteps", "cond_layers"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"DenoiserConfig.{name} must be an integer >= 1, got {v!r}")
        if self.d_model % self.n_heads:
            raise ValueError(f"d_model ({self.d_model}) must be divisible by n_heads "
                             f"({self.n_heads})")
        if self.d_model % 2:
            raise ValueError(f"d_model must be even (sinusoidal embedding), got {self.d_model}")
        for name in ("dropout", "cond_drop_prob"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ValueError(f"DenoiserConfig.{name} must lie in [0, 1), got "
                                 f"{getattr(self, name)}")

    @property
    def n_joint_frames(self):
        """N: joint frames of a window (``n_frames + 1`` rows for ``"relative"`` features,
        ``n_frames`` for ``"absolute"``)."""
        return self.n_frames - REPRESENTATIONS[self.representation][1]

    @classmethod
    def for_representation(cls, representation="relative", n_joint_frames=40, **kwargs):
        """A config whose ``feature_dim`` and ``n_frames`` fit ``representation`` for windows
        of ``n_joint_frames`` frames (other fields from ``kwargs``)."""
        dim, extra = REPRESENTATIONS[check_representation(representation)]
        return cls(feature_dim=dim, n_frames=n_joint_frames + extra,
                   representation=representation, **kwargs)

    def to_dict(self):
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d):
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown DenoiserConfig keys {unknown}; expected a subset of "
                             f"{sorted(known)}")
        return cls(**d)


def count_parameters(module, trainable_only=False):
    """Number of parameters of a module (only those with ``requires_grad`` if asked)."""
    return sum(p.numel() for p in module.parameters() if p.requires_grad or not trainable_only)


# ----------------------------------------------------------------------------- features -> joints


def _rotate_y_torch(v, angle):
    """``R_y(angle) v`` for v ``(..., 3)`` and angle broadcastable to ``v[..., 0]``."""
    c, s = torch.cos(angle), torch.sin(angle)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return torch.stack([c * x + s * z, y, -s * x + c * z], dim=-1)


def features_to_joints_torch(features, include_last=True, representation="relative"):
    """Differentiable :func:`~physlab.motion.features.features_to_joints` for a batch, from
    the canonical start (heading 0, pelvis at ``x = z = 0``). Sketch2Anim's ``R(.)``
    (Eq. (6)).

    Parameters
    ----------
    features : (B, T, D) tensor of denormalised feature rows (D = 137; 70 for
        ``representation="absolute"``, :func:`~physlab.motion.features.
        absolute_features_to_joints`, whose T rows are T frames).
    include_last : bool, also return frame ``T`` from the last joint velocities (relative
        features only).

    Returns
    -------
    (B, T + 1, 22, 3) tensor (``(B, T, 22, 3)`` without the last frame or for absolute
    features), metres.
    """
    if check_representation(representation) == "absolute":
        if features.ndim != 3 or features.shape[-1] != ABS_FEATURE_DIM:
            raise ValueError(f"features must have shape (B, T, {ABS_FEATURE_DIM}), got "
                             f"{tuple(features.shape)}")
        B, n, _ = features.shape
        p = features[..., None, ABS_PELVIS]                                # (B, T, 1, 3)
        return torch.cat([p, p + features[..., ABS_BODY].reshape(B, n, N_JOINTS - 1, 3)], 2)
    if features.ndim != 3 or features.shape[-1] != FEATURE_DIM:
        raise ValueError(f"features must have shape (B, T, {FEATURE_DIM}), got "
                         f"{tuple(features.shape)}")
    B, n, _ = features.shape
    if n == 0:
        raise ValueError("features has no rows; a motion of T frames has T-1 rows")
    f = features
    ang = f[..., ROOT_ANG_VEL.start]                                       # (B, T)
    theta = torch.cat([torch.zeros_like(ang[:, :1]), torch.cumsum(ang[:, :-1], dim=1)], dim=1)
    lin = f[..., ROOT_LIN_VEL]                                             # (B, T, 2)
    step = torch.stack([lin[..., 0], torch.zeros_like(lin[..., 0]), lin[..., 1]], dim=-1)
    step = _rotate_y_torch(step, theta)                                    # (B, T, 3) world
    root = torch.cat([torch.zeros_like(step[:, :1]), torch.cumsum(step[:, :-1], dim=1)], dim=1)
    ric = f[..., RIC].reshape(B, n, N_JOINTS - 1, 3)                       # (B, T, 21, 3)
    body = _rotate_y_torch(ric, theta[..., None])                          # (B, T, 21, 3)
    body = body + root[:, :, None] * body.new_tensor([1.0, 0.0, 1.0])
    pelvis = torch.stack([root[..., 0], f[..., ROOT_HEIGHT.start], root[..., 2]], dim=-1)
    x = torch.cat([pelvis[:, :, None], body], dim=2)                       # (B, T, 22, 3)
    if include_last:
        vel = f[:, -1, LOCAL_VEL].reshape(B, N_JOINTS, 3)                  # (B, 22, 3)
        last = x[:, -1] + _rotate_y_torch(vel, theta[:, -1, None])         # (B, 22, 3)
        x = torch.cat([x, last[:, None]], dim=1)                           # (B, T+1, 22, 3)
    return x


# ----------------------------------------------------------------------------- building blocks


def low_pass_matrix(n, k):
    """``(n, n)`` projection onto the ``k`` lowest-frequency DCT-II basis vectors of length
    ``n``: ``P = C_kᵀ C_k`` with ``C`` the orthonormal DCT matrix. ``P @ x`` keeps a
    sequence's slow part (for 40 frames at 20 fps, ``k = 16`` keeps frequencies below
    4 Hz); ``P`` is symmetric and idempotent."""
    i = torch.arange(n, dtype=torch.float64)
    C = torch.cos(math.pi * (i[None] + 0.5) * i[:, None] / n) * math.sqrt(2.0 / n)   # (n, n)
    C[0] /= math.sqrt(2.0)
    return (C[:k].T @ C[:k]).to(torch.float32)


def timestep_embedding(t, dim, max_period=10000):
    """Sinusoidal embedding of integer timesteps (Vaswani et al. 2017; DDPM): ``(B,)`` ->
    ``(B, dim)`` with ``[cos(t w_k), sin(t w_k)]``, ``w_k = max_period^(-k / (dim/2))``."""
    half = dim // 2
    freqs = torch.exp(-math.log(max_period) * torch.arange(half, dtype=torch.float32,
                                                           device=t.device) / half)
    args = t.float()[:, None] * freqs[None]                                # (B, dim/2)
    return torch.cat([torch.cos(args), torch.sin(args)], dim=-1)           # (B, dim)


class Dropout(nn.Module):
    """Inverted dropout (``nn.Dropout``'s contract) with a cheaper mask: each element's keep
    test reads 16 random bits, drawn four to one 64-bit ``torch.randint`` draw, against
    ``nn.Dropout``'s one Bernoulli draw per element. On a 2-core AMD EPYC the random draws were
    most of the cost of dropout, and dropout a quarter of a control-stage training step
    (``cProfile``, 2026-11-27); this one is 3x faster, and bf16 training 1.1-1.25x
    (``benchmarks/bench_motion.py`` measures it against ``nn.Dropout`` in the same run).
    The drop probability is ``p`` rounded to a multiple of 2**-16 (below 2**-17 it is 0);
    kept elements are scaled by ``1 / (1 - p)`` for that rounded ``p``, so the expectation is
    exact. Identity in eval mode and for ``p = 0``; no parameters, so ``state_dict`` keys are
    those of ``nn.Dropout``."""

    def __init__(self, p: float = 0.5):
        super().__init__()
        if not (isinstance(p, (int, float)) and 0 <= p < 1):
            raise ValueError(f"dropout probability must be in [0, 1), got {p!r}")
        self.p = float(p)
        self._drop = round(self.p * 65536)                 # dropped 16-bit values, of 65536
        self._scale = 65536 / (65536 - self._drop)

    def extra_repr(self):
        return f"p={self.p}"

    def forward(self, x):
        if not self.training or self._drop == 0:
            return x
        n = x.numel()
        bits = torch.randint(-2**63, 2**63 - 1, ((n + 3) // 4,), dtype=torch.int64,
                             device=x.device).view(torch.int16)[:n].view(x.shape)
        keep = (bits >= self._drop - 32768).to(x.dtype).mul_(self._scale)   # 0 or 1 / (1 - p)
        return x * keep


class SelfAttention(nn.Module):
    """Multi-head self-attention written out (nanoGPT style, not causal). Written by hand
    rather than ``nn.MultiheadAttention``, whose inference fast path is taken or not
    depending on ``requires_grad`` and changes results by ~1e-6: the zero-init property
    (controlled output == base output) is then exact."""

    def __init__(self, d_model, n_heads, dropout):
        super().__init__()
        self.n_heads = n_heads
        self.qkv = nn.Linear(d_model, 3 * d_model)
        self.proj = nn.Linear(d_model, d_model)
        self.attn_drop = Dropout(dropout)

    def forward(self, h):                                                  # (B, L, C)
        B, L, C = h.shape
        q, k, v = self.qkv(h).split(C, dim=2)                              # 3 x (B, L, C)
        q, k, v = (u.view(B, L, self.n_heads, C // self.n_heads).transpose(1, 2)
                   for u in (q, k, v))                                     # (B, H, L, C/H)
        att = (q @ k.transpose(-2, -1)) / math.sqrt(k.shape[-1])           # (B, H, L, L)
        att = self.attn_drop(att.softmax(dim=-1))
        y = (att @ v).transpose(1, 2).reshape(B, L, C)                     # (B, L, C)
        return self.proj(y)


class Block(nn.Module):
    """Pre-LayerNorm transformer encoder block: ``h + attn(ln(h))``, then ``h + mlp(ln(h))``."""

    def __init__(self, d_model, n_heads, ff, dropout):
        super().__init__()
        self.ln1 = nn.LayerNorm(d_model)
        self.attn = SelfAttention(d_model, n_heads, dropout)
        self.ln2 = nn.LayerNorm(d_model)
        self.mlp = nn.Sequential(nn.Linear(d_model, ff), nn.GELU(), nn.Linear(ff, d_model),
                                 Dropout(dropout))
        self.drop = Dropout(dropout)

    def forward(self, h):                                                  # (B, L, C)
        h = h + self.drop(self.attn(self.ln1(h)))
        return h + self.mlp(self.ln2(h))                                   # (B, L, C)


def _zero_linear(d_in, d_out):
    """A linear layer with zero weight and bias (ControlNet's 'zero convolution' Z)."""
    lin = nn.Linear(d_in, d_out)
    nn.init.zeros_(lin.weight)
    nn.init.zeros_(lin.bias)
    return lin


class DenoiserEncoder(nn.Module):
    """Input layers and transformer blocks of the denoiser (the part ControlNet copies)."""

    def __init__(self, cfg: DenoiserConfig):
        super().__init__()
        C = cfg.d_model
        self.d_model = C
        self.motion_in = nn.Linear(cfg.feature_dim, C)
        self.pos = nn.Parameter(torch.randn(1, cfg.n_frames + 1, C) * 0.02)   # cond + rows
        self.time_mlp = nn.Sequential(nn.Linear(C, C), nn.SiLU(), nn.Linear(C, C))
        self.text_proj = nn.Linear(cfg.text_dim, C)
        self.null_text = nn.Parameter(torch.zeros(cfg.text_dim))   # a of the unconditional model
        self.drop = Dropout(cfg.dropout)
        self.blocks = nn.ModuleList([Block(C, cfg.n_heads, cfg.ff, cfg.dropout)
                                     for _ in range(cfg.n_layers)])

    def tokens(self, x_t, t, text_emb, drop_text=None, motion_extra=None, cond_extra=None):
        """Input tokens ``(B, 1 + T, C)``: the condition token (time + text, plus
        ``cond_extra`` (B, C)) and the motion rows (plus ``motion_extra`` (B, T, C))."""
        if drop_text is not None:
            drop = drop_text.to(torch.bool).reshape(-1, 1)                 # (B, 1)
            text_emb = torch.where(drop, self.null_text.expand_as(text_emb), text_emb)
        c = self.time_mlp(timestep_embedding(t, self.d_model)) + self.text_proj(text_emb)  # (B, C)
        if cond_extra is not None:
            c = c + cond_extra
        m = self.motion_in(x_t)                                            # (B, T, C)
        if motion_extra is not None:
            m = m + motion_extra
        h = torch.cat([c[:, None], m], dim=1) + self.pos                   # (B, 1+T, C)
        return self.drop(h)

    def run_blocks(self, h, residuals=None):
        """Run the blocks, adding ``residuals[i]`` (B, 1+T, C) after block ``i``; returns the
        list of block outputs (each (B, 1+T, C))."""
        outs = []
        for i, block in enumerate(self.blocks):
            h = block(h)
            if residuals is not None:
                h = h + residuals[i]
            outs.append(h)
        return outs


def _check_inputs(x_t, t, text_emb, cfg, drop_text=None):
    if x_t.ndim != 3 or x_t.shape[1:] != (cfg.n_frames, cfg.feature_dim):
        raise ValueError(f"x_t must have shape (B, {cfg.n_frames}, {cfg.feature_dim}) "
                         f"(batch, feature rows, features), got {tuple(x_t.shape)}")
    B = x_t.shape[0]
    if not torch.is_tensor(t) or t.shape != (B,) or t.is_floating_point():
        raise ValueError(f"t must be a ({B},) integer tensor of timesteps, got "
                         f"{getattr(t, 'shape', t)!r}")
    if t.numel() and (int(t.min()) < 0 or int(t.max()) >= cfg.max_timesteps):
        raise ValueError(f"t must lie in 0..{cfg.max_timesteps - 1} (max_timesteps), got "
                         f"values in {int(t.min())}..{int(t.max())}")
    if text_emb.shape != (B, cfg.text_dim):
        raise ValueError(f"text_emb must have shape ({B}, {cfg.text_dim}) (one action embedding "
                         f"per sample, see physlab.motion.text), got {tuple(text_emb.shape)}")
    if drop_text is not None and tuple(drop_text.shape) != (B,):
        raise ValueError(f"drop_text must be None or a ({B},) bool tensor, got "
                         f"{tuple(drop_text.shape)}")
    if not torch.isfinite(x_t).all():
        raise ValueError("x_t contains NaN or inf")
    if not torch.isfinite(text_emb).all():
        raise ValueError("text_emb contains NaN or inf")


class MotionDenoiser(nn.Module):
    """``eps_theta(x_t, t, a)``: text-conditioned denoising transformer over feature rows
    (predicts x₀, ε or v, as the checkpoint's scheduler says).

    **Skip connection** (``config.skip``, x₀-prediction): the output is
    ``x̂₀ = √ᾱ_t x_t + √(1 − ᾱ_t) F(x_t, t, a)`` with ``F`` the transformer's head — the
    preconditioning of Karras et al. 2022 (EDM, Table 1: ``c_skip = σ_d² / (σ² +
    σ_d²)``, ``c_out = σ σ_d / √(σ² + σ_d²)``) written for the variance-preserving process with
    ``σ_d = 1`` (normalised features): ``√ᾱ_t x_t`` is the best linear guess of x₀ from x_t and
    ``√(1 − ᾱ_t)`` the size of what it misses. Near t = 0 the identity comes free and the
    network learns only a small correction; near T it predicts x₀ as before (``√ᾱ_T ≈
    0.07``). ``config.skip_pelvis = False`` leaves the pelvis position columns plain x₀ (the
    pose columns keep the skip). Without it the shipped 0.9 M-parameter x₀ model damped a real wave it was handed
    at t = 20 (almost no noise) to 78 % of its wrist travel in one step. The ᾱ_t table comes
    from the checkpoint's scheduler (:meth:`set_schedule`), not from the weights.
    """

    def __init__(self, cfg: DenoiserConfig):
        super().__init__()
        self.config = cfg
        self.encoder = DenoiserEncoder(cfg)
        self.ln_f = nn.LayerNorm(cfg.d_model)
        self.head = nn.Linear(cfg.d_model, cfg.feature_dim)
        if cfg.smooth_basis:
            self.register_buffer("low_pass", low_pass_matrix(cfg.n_frames, cfg.smooth_basis),
                                 persistent=False)
        else:
            self.low_pass = None
        #: ``(T_diff,)`` √ᾱ_t and √(1 − ᾱ_t) of the skip connection (:meth:`set_schedule`)
        self.register_buffer("skip_scale", torch.zeros(0), persistent=False)
        self.register_buffer("out_scale", torch.zeros(0), persistent=False)
        mask = torch.ones(cfg.feature_dim)                  # columns under the skip connection
        if not cfg.skip_pelvis:
            mask[ABS_PELVIS] = 0.0
        self.register_buffer("skip_mask", mask, persistent=False)
        #: None or a tuple of ``(mask, P)`` pairs: the feature columns where ``mask`` (D,) is 1
        #: keep only the frequencies of ``P`` (a narrower :func:`low_pass_matrix`; set by the
        #: sampler for the pelvis path and the joints other than the arms of a text-only clip,
        #: :data:`~physlab.motion.sampling.PATH_FREQUENCIES` and
        #: :data:`~physlab.motion.sampling.BODY_FREQUENCIES`).
        self.column_low_pass = None

    def set_schedule(self, alphas_cumprod):
        """Give the skip connection (``config.skip``) its ``ᾱ_t``: a ``(max_timesteps,)``
        sequence in (0, 1], e.g. :attr:`NoiseScheduler.alphas_cumprod`. A model without the
        skip connection ignores it. Returns ``self``."""
        if not self.config.skip:
            return self
        a = torch.as_tensor(alphas_cumprod, dtype=torch.float64).reshape(-1)
        if a.numel() != self.config.max_timesteps or not bool(((a > 0) & (a <= 1)).all()):
            raise ValueError(f"alphas_cumprod must hold {self.config.max_timesteps} values in "
                             f"(0, 1] (the scheduler's ᾱ_t), got {a.numel()} values in "
                             f"[{float(a.min()) if a.numel() else 'nan'}, "
                             f"{float(a.max()) if a.numel() else 'nan'}]")
        self.skip_scale = a.sqrt().to(torch.float32)
        self.out_scale = (1 - a).sqrt().to(torch.float32)
        return self

    def smooth(self, v):
        """``v`` (B, T, D) in the output basis: the :attr:`low_pass` rows, then the
        :attr:`column_low_pass` columns (what :meth:`forward` does to the head's output)."""
        if self.low_pass is not None:                                      # K lowest frequencies
            v = torch.einsum("st,btd->bsd", self.low_pass.to(v.dtype), v)
        for mask, P in self.column_low_pass or ():
            mask = mask.to(v.dtype)
            v = v + mask * (torch.einsum("st,btd->bsd", P.to(v.dtype), v) - v)
        return v

    def forward(self, x_t, t, text_emb, drop_text=None, residuals=None, out_extra=None):
        """Predicted noise.

        Parameters
        ----------
        x_t : (B, T, D) noisy normalised features; t : (B,) int64 timesteps;
        text_emb : (B, text_dim) action embeddings a;
        drop_text : None or (B,) bool, True -> unconditional (null text), for CFG;
        residuals : None or list of n_layers tensors (B, 1+T, C) added after each block;
        out_extra : None or (B, T, D) added to the output after the skip connection, unscaled
            (the control head of :class:`ControlledDenoiser`).

        Returns
        -------
        (B, T, D) tensor: x̂₀, ε̂ or v̂ (the scheduler's ``prediction_type``).
        """
        _check_inputs(x_t, t, text_emb, self.config, drop_text)
        if residuals is not None and len(residuals) != len(self.encoder.blocks):
            raise ValueError(f"need one residual per block ({len(self.encoder.blocks)}), got "
                             f"{len(residuals)}")
        h = self.encoder.tokens(x_t, t, text_emb, drop_text)               # (B, 1+T, C)
        h = self.encoder.run_blocks(h, residuals)[-1]                      # (B, 1+T, C)
        return self.output(h, x_t, t, out_extra)

    def output(self, h, x_t, t, out_extra=None):
        """The head on the last block output ``h`` (B, 1+T, C): ``(B, T, D)`` x̂₀ / ε̂ / v̂,
        with the skip connection, ``out_extra`` and the low-pass basis (the end of
        :meth:`forward`, shared with :class:`FusedControlledDenoiser`)."""
        out = self.head(self.ln_f(h[:, 1:]))                               # (B, T, D)
        if self.config.skip:
            if not self.skip_scale.numel():
                raise RuntimeError("this denoiser has a skip connection (config.skip) but no "
                                   "noise schedule: call set_schedule(scheduler.alphas_cumprod)"
                                   " (load_model does)")
            skipped = (self.skip_scale[t].to(out.dtype)[:, None, None] * x_t
                       + self.out_scale[t].to(out.dtype)[:, None, None] * out)  # c_skip, c_out
            m = self.skip_mask.to(out.dtype)
            out = m * skipped + (1 - m) * out
        if out_extra is not None:
            out = out + out_extra
        return self.smooth(out)


# ----------------------------------------------------------------------------- conditions


class FrameConditionEncoder(nn.Module):
    """Per-frame condition ``(B, N, F)`` -> per-row embedding ``(B, N-1, C)``: a linear
    input layer, ``cond_layers`` transformer blocks over the N frames, then row ``i`` =
    ``Linear([e_i, e_{i+1}])`` (a feature row is built from frames i and i+1). The output
    layer has PyTorch's default initialisation, *not* zero: the ControlNet's output layers
    ``Z_i`` and the adapter's ``Z'_i`` are already zero, so the controlled model starts equal
    to the base anyway, and a third zero factor on the trajectory path (E_tr -> copy -> Z ->
    adapter -> Z') left the gradients of the trajectory branch at zero: a control stage trained
    1500 steps with a zero-initialised E_tr and E_k still ignored the conditions (held-out
    trajectory error 0.336 m with, 0.336 m without them). This is ``E_tr`` (Eq. (1)) with ``F = 6*3 + 6`` (positions + mask); a 2D variant would
    use ``F = 6*2 + 6``."""

    def __init__(self, in_dim, cfg: DenoiserConfig):
        super().__init__()
        C = cfg.d_model
        self.in_dim = in_dim
        self.pairs = cfg.n_frames < cfg.n_joint_frames      # relative rows: frames i and i+1
        self.inp = nn.Linear(in_dim, C)
        self.pos = nn.Parameter(torch.randn(1, cfg.n_joint_frames, C) * 0.02)
        self.blocks = nn.ModuleList([Block(C, cfg.n_heads, cfg.ff, cfg.dropout)
                                     for _ in range(cfg.cond_layers)])
        self.out = nn.Linear(2 * C if self.pairs else C, C)

    def forward(self, frames):                                             # (B, N, F)
        e = self.inp(frames) + self.pos                                    # (B, N, C)
        for block in self.blocks:
            e = block(e)
        if not self.pairs:                                                 # absolute: row = frame
            return self.out(e)                                             # (B, N, C)
        return self.out(torch.cat([e[:, :-1], e[:, 1:]], dim=-1))          # (B, N-1, C)


def trajectory_frames(trajectory, mask):
    """``(B, N, 6, 3)`` trajectory and ``(B, N, 6)`` mask -> ``(B, N, 24)`` per-frame input
    of :class:`FrameConditionEncoder` (positions zeroed where the mask is False)."""
    m = mask.to(trajectory.dtype)
    traj = trajectory * m[..., None]                                       # (B, N, 6, 3)
    return torch.cat([traj.flatten(2), m], dim=-1)                         # (B, N, 24)


class KeyposeEncoder(nn.Module):
    """``E_k(K)`` (Eq. (2)): keypose ``(B, 22, 3)`` + key frame ``(B,)`` -> ``(B, C)``.

    The pose is made pelvis-relative in x and z (the keypose gives no global placement,
    Sec. 4.2; heights kept), each joint is a token (position + learned joint embedding), one
    transformer block mixes them, the tokens are mean-pooled and a learned embedding of the
    key frame index is added. Output layer with default initialisation (see
    :class:`FrameConditionEncoder` for why not zero)."""

    def __init__(self, cfg: DenoiserConfig, coord_dim=3):
        super().__init__()
        C = cfg.d_model
        self.coord_dim = coord_dim
        self.inp = nn.Linear(coord_dim, C)
        self.joint = nn.Parameter(torch.randn(1, N_JOINTS, C) * 0.02)
        self.frame = nn.Embedding(cfg.n_joint_frames, C)
        self.blocks = nn.ModuleList([Block(C, cfg.n_heads, cfg.ff, cfg.dropout)
                                     for _ in range(cfg.cond_layers)])
        self.out = nn.Linear(C, C)

    def forward(self, keypose, key_frame):                                 # (B, J, 3), (B,)
        rel = keypose.clone()
        rel[..., 0] = keypose[..., 0] - keypose[:, :1, 0]
        rel[..., 2] = keypose[..., 2] - keypose[:, :1, 2]
        e = self.inp(rel) + self.joint                                     # (B, J, C)
        for block in self.blocks:
            e = block(e)
        return self.out(e.mean(dim=1) + self.frame(key_frame))             # (B, C)


#: Numbers describing a storyboard camera to the 2D encoders (:func:`camera_features`).
CAMERA_FEATURES = 7
#: Transformer blocks in each 2D encoder (the 3D ones have ``cond_layers`` = 1): lifting a
#: drawing needs more than reading 3D points.
SKETCH_LAYERS = 2


def camera_features(camera):
    """``(B, 4)`` cameras ``[scale, pitch, yaw, roll]`` (degrees, :class:`~physlab.motion.
    camera.Camera`) -> ``(B, 7)`` inputs of the 2D encoders: ``scale - 1`` and the sine and
    cosine of each angle (continuous over the angle's whole range)."""
    if camera.ndim != 2 or camera.shape[-1] != 4:
        raise ValueError(f"camera must have shape (B, 4) = [scale, pitch, yaw, roll], got "
                         f"{tuple(camera.shape)}")
    ang = torch.deg2rad(camera[:, 1:])
    return torch.cat([camera[:, :1] - 1.0, torch.sin(ang), torch.cos(ang)], dim=-1)


def sketch_trajectory_frames(trajectory_2d, mask, camera):
    """``(B, N, 6, 2)`` drawn trajectories, ``(B, N, 6)`` mask and ``(B, 4)`` cameras ->
    ``(B, N, 6*2 + 6 + 7)`` per-frame input of ``E^2D_tr`` (points zeroed where the mask is
    False; the camera's :func:`camera_features` repeated on every frame)."""
    m = mask.to(trajectory_2d.dtype)
    traj = (trajectory_2d * m[..., None]).flatten(2)                       # (B, N, 12)
    cam = camera_features(camera)[:, None].expand(-1, mask.shape[1], -1)   # (B, N, 7)
    return torch.cat([traj, m, cam], dim=-1)


class SketchKeyposeEncoder(nn.Module):
    """``E^2D_k`` (Sec. 5): a drawn keypose ``(B, 22, 2)`` (normalised image units), its key
    frame ``(B,)`` and the camera ``(B, 4)`` -> ``(B, C)``, trained to land on the 3D keypose
    encoder's embedding of the same pose (Eqs. (10)–(13)).

    The pose is made pelvis-relative in both image axes (a drawing's placement says nothing
    of the pose), each joint is a token of its 2D position and the :func:`camera_features`
    plus a learned joint embedding; :data:`SKETCH_LAYERS` blocks mix them, then mean-pooling,
    a key-frame embedding and an output layer, as in :class:`KeyposeEncoder`."""

    def __init__(self, cfg: DenoiserConfig):
        super().__init__()
        C = cfg.d_model
        self.inp = nn.Linear(2 + CAMERA_FEATURES, C)
        self.joint = nn.Parameter(torch.randn(1, N_JOINTS, C) * 0.02)
        self.frame = nn.Embedding(cfg.n_joint_frames, C)
        self.blocks = nn.ModuleList([Block(C, cfg.n_heads, cfg.ff, cfg.dropout)
                                     for _ in range(SKETCH_LAYERS)])
        self.out = nn.Linear(C, C)

    def forward(self, keypose_2d, key_frame, camera):                      # (B, J, 2), (B,), (B, 4)
        rel = keypose_2d - keypose_2d[:, :1]
        cam = camera_features(camera)[:, None].expand(-1, N_JOINTS, -1)    # (B, J, 7)
        e = self.inp(torch.cat([rel, cam], dim=-1)) + self.joint           # (B, J, C)
        for block in self.blocks:
            e = block(e)
        return self.out(e.mean(dim=1) + self.frame(key_frame))             # (B, C)


def sketch_trajectory_encoder(cfg: DenoiserConfig):
    """``E^2D_tr`` (Sec. 5): a :class:`FrameConditionEncoder` over
    :func:`sketch_trajectory_frames` with :data:`SKETCH_LAYERS` blocks."""
    return FrameConditionEncoder(2 * N_TRAJ + N_TRAJ + CAMERA_FEATURES,
                                 dataclasses.replace(cfg, cond_layers=SKETCH_LAYERS))


def unified_frames(trajectory, mask, keypose, key_frame, keypose_mask=None):
    """Single-ControlNet condition (Table 2): trajectory, mask, the keypose written into its
    frame (``K_3D``, zeros elsewhere) and a one-hot key frame: ``(B, N, 24 + 66 + 1)``
    (keypose and one-hot zero for samples whose ``keypose_mask`` (B,) is False)."""
    N = mask.shape[1]
    onehot = F.one_hot(key_frame, N).to(trajectory.dtype)                  # (B, N)
    if keypose_mask is not None:
        onehot = onehot * keypose_mask.to(onehot.dtype)[:, None]
    dense = onehot[..., None] * keypose.flatten(1)[:, None]                # (B, N, 66)
    return torch.cat([trajectory_frames(trajectory, mask), dense, onehot[..., None]], dim=-1)


def check_condition(cond, batch, n_joint_frames):
    """Validate a condition dict (``trajectory`` (B, N, 6, 3), ``traj_mask`` (B, N, 6) bool,
    ``keypose`` (B, 22, 3), ``key_frame`` (B,) int in 0..N-1, ``N = n_joint_frames``);
    ValueError saying what is wrong."""
    N = n_joint_frames
    need = {"trajectory": (batch, N, N_TRAJ, 3), "traj_mask": (batch, N, N_TRAJ),
            "keypose": (batch, N_JOINTS, 3), "key_frame": (batch,)}
    if not isinstance(cond, dict):
        raise TypeError(f"cond must be a dict with keys {sorted(need)}, got "
                         f"{type(cond).__name__}")
    missing = sorted(set(need) - set(cond))
    if missing:
        raise ValueError(f"cond is missing {missing}; build it with physlab.motion.train."
                         f"condition_batch")
    for k, shape in need.items():
        if tuple(cond[k].shape) != shape:
            hint = (f" ({N_TRAJ} trajectory joints {TRAJECTORY_JOINTS} in dataset order)"
                    if k in ("trajectory", "traj_mask") else
                    f" ({N_JOINTS} joints)" if k == "keypose" else "")
            raise ValueError(f"cond[{k!r}] must have shape {shape}{hint}, got "
                             f"{tuple(cond[k].shape)}")
    for k in ("trajectory", "keypose"):
        if not torch.isfinite(cond[k]).all():
            raise ValueError(f"cond[{k!r}] contains NaN or inf")
    km = cond.get("keypose_mask")
    if km is not None and (tuple(km.shape) != (batch,) or km.dtype != torch.bool):
        raise ValueError(f"cond['keypose_mask'] must be None or a ({batch},) bool tensor "
                         f"(False: no keypose), got {getattr(km, 'dtype', None)} "
                         f"{tuple(getattr(km, 'shape', ()))}")
    kf = cond["key_frame"]
    if kf.is_floating_point() or (kf.numel() and (int(kf.min()) < 0 or int(kf.max()) >= N)):
        raise ValueError(f"cond['key_frame'] must hold integer frame indices in 0..{N - 1}")
    sketch = {"trajectory_2d": (batch, N, N_TRAJ, 2), "traj_mask_2d": (batch, N, N_TRAJ),
              "keypose_2d": (batch, N_JOINTS, 2), "camera": (batch, 4)}
    given = [k for k in sketch if k in cond]
    if given:
        if "camera" not in cond:
            raise ValueError("cond has 2D conditions but no 'camera' (B, 4) = [scale, pitch, "
                             "yaw, roll]: a drawing needs the view it was drawn in")
        if ("trajectory_2d" in cond) != ("traj_mask_2d" in cond):
            raise ValueError("cond needs 'trajectory_2d' and 'traj_mask_2d' together")
        for k in given:
            if tuple(cond[k].shape) != sketch[k]:
                raise ValueError(f"cond[{k!r}] must have shape {sketch[k]}, got "
                                 f"{tuple(cond[k].shape)}")
            if cond[k].dtype != torch.bool and not torch.isfinite(cond[k]).all():
                raise ValueError(f"cond[{k!r}] contains NaN or inf")


#: Std (times 1/sqrt(C)) of the initial weights of the ControlNet's output layers Z_i in
#: the ControlNet + adapter model (:class:`ControlledDenoiser`; the adapter's Z'_i stay zero).
CONTROLNET_INIT_STD = 0.1

#: Sketch2Anim Table 2's variants of the controlled model -> the constructor keyword and
#: checkpoint key that selects it (the ControlNet + keypose adapter, the paper's method, has none).
CONTROLNET_VARIANTS = {"adapter": None, "single": "single_controlnet",
                       "double": "double_controlnet"}


def controlnet_variant(source):
    """``"adapter"``, ``"single"`` or ``"double"``: the Table 2 variant of a
    :class:`ControlledDenoiser` or of a checkpoint dict (its ``single_controlnet`` /
    ``double_controlnet`` flags; a missing flag means off, as in older checkpoints)."""
    flag = (source.get if isinstance(source, dict)
            else lambda key, default: getattr(source, key, default))
    on = [name for name, key in CONTROLNET_VARIANTS.items() if key and flag(key, False)]
    if len(on) > 1:
        raise ValueError(f"both {' and '.join(CONTROLNET_VARIANTS[n] for n in on)} are set; "
                         f"they are two different Table 2 ablations")
    return on[0] if on else "adapter"


def controlnet_variant_label(variant):
    """How messages name a :data:`CONTROLNET_VARIANTS` key: ``"ControlNet + adapter"``,
    ``"single-ControlNet"`` or ``"double-ControlNet"``."""
    return "ControlNet + adapter" if variant == "adapter" else f"{variant}-ControlNet"


class TrajectoryControlNet(nn.Module):
    """``r = F_tr(z_t + E_tr(T), t, a)`` (Eq. (1)): a trainable copy of the base encoder
    plus one zero-initialised linear layer ``Z_i`` per block.

    Parameters
    ----------
    base : :class:`MotionDenoiser` whose encoder is copied (weights included).
    cond_encoder : module ``(B, N, F) -> (B, N-1, C)``; default
        ``FrameConditionEncoder(24)`` on :func:`trajectory_frames`.
    """

    def __init__(self, base: MotionDenoiser, cond_encoder=None):
        super().__init__()
        cfg = base.config
        self.encoder = copy.deepcopy(base.encoder)
        for p in self.encoder.parameters():
            p.requires_grad_(True)
        self.cond_encoder = cond_encoder or FrameConditionEncoder(3 * N_TRAJ + N_TRAJ, cfg)
        self.zero = nn.ModuleList([_zero_linear(cfg.d_model, cfg.d_model)
                                   for _ in range(cfg.n_layers)])

    def forward(self, x_t, t, text_emb, frames, drop_text=None):
        """``frames`` (B, N, F) per-frame condition -> list of residuals (B, 1+T, C)."""
        return self.from_embedding(x_t, t, text_emb, self.cond_encoder(frames), drop_text)

    def from_embedding(self, x_t, t, text_emb, e, drop_text=None, with_hidden=False):
        """Residuals from a condition embedding ``e`` (B, T, C) (``E_tr(T)`` or, aligned with
        it, ``E^2D_tr`` of a drawing); ``with_hidden``: ``(residuals, last block output
        (B, 1+T, C))``, the input of :class:`ControlledDenoiser`'s control head."""
        h = self.encoder.tokens(x_t, t, text_emb, drop_text, motion_extra=e)  # Eq. (1) z'_t
        outs = self.encoder.run_blocks(h)
        res = [z(o) for z, o in zip(self.zero, outs)]
        return (res, outs[-1]) if with_hidden else res


class KeyposeAdapter(nn.Module):
    """``r' = F_k(z_t, t, r, a')``, ``a' = a + E_k(K)`` (Eqs. (2)–(3)): a trainable copy of
    the base encoder whose blocks receive the ControlNet residuals ``r`` and whose outputs go
    through zero-initialised linear layers ``Z'_i``."""

    def __init__(self, base: MotionDenoiser, keypose_encoder=None):
        super().__init__()
        cfg = base.config
        self.encoder = copy.deepcopy(base.encoder)
        for p in self.encoder.parameters():
            p.requires_grad_(True)
        self.keypose_encoder = keypose_encoder or KeyposeEncoder(cfg)
        self.zero = nn.ModuleList([_zero_linear(cfg.d_model, cfg.d_model)
                                   for _ in range(cfg.n_layers)])

    def forward(self, x_t, t, text_emb, keypose, key_frame, residuals, drop_text=None,
                keypose_mask=None):
        return self.from_embedding(x_t, t, text_emb, self.keypose_encoder(keypose, key_frame),
                                   residuals, drop_text, keypose_mask)

    def from_embedding(self, x_t, t, text_emb, k, residuals, drop_text=None,
                       keypose_mask=None, with_hidden=False):
        """Residuals ``r'`` from a keypose embedding ``k`` (B, C) (``E_k(K)`` or ``E^2D_k``);
        ``with_hidden`` as for :meth:`TrajectoryControlNet.from_embedding`."""
        if keypose_mask is not None:                                       # no keypose: a' = a
            k = k * keypose_mask.to(k.dtype)[:, None]
        h = self.encoder.tokens(x_t, t, text_emb, drop_text, cond_extra=k)  # Eq. (2) a'
        outs = self.encoder.run_blocks(h, residuals)                        # Eq. (3)
        res = [z(o) for z, o in zip(self.zero, outs)]
        return (res, outs[-1]) if with_hidden else res


class ControlledDenoiser(nn.Module):
    """Frozen base denoiser + trajectory ControlNet + keypose adapter (Eq. (4)):
    ``eps = eps_theta(x_t, t, a; residuals = r')``.

    Parameters
    ----------
    base : trained :class:`MotionDenoiser`; frozen (``requires_grad=False``, kept in eval
        mode so its dropout is off).
    single_controlnet : bool, the Table 2 "Single ControlNet" ablation: one ControlNet over
        the unified trajectory + keypose matrix (:func:`unified_frames`), no adapter.
    double_controlnet : bool, the Table 2 "Double ControlNet" ablation (supp. A.2): the
        keypose branch (``self.adapter``: ``a' = a + E_k(K)``, its own copy of the encoder and
        zero layers) runs beside the trajectory ControlNet instead of on its residuals, and
        the two residual lists are added, ``r + r'``, before they enter the base.
    traj_encoder, keypose_encoder : optional replacements of ``E_tr`` / ``E_k``.
    control_head : bool, also add ``H(h_L)`` to the base's output *after* its skip connection
        (``self.control_head``: LayerNorm + a zero-initialised linear layer on the last block
        output ``h_L`` of the branch that feeds the base — the adapter, or the ControlNet of
        the single-ControlNet ablation; with the double ControlNet, the sum of both). Not in
        the paper: on a base with a skip connection (``config.skip``) the residuals reach x̂₀
        only through ``√(1 − ᾱ_t) F``, so near t = 0 the branches can hardly move it; the head
        acts on x̂₀ unscaled. Zero at initialisation, so the controlled model still starts
        equal to the base.
    sketch_encoders : bool, also build the 2D encoders ``E^2D_tr``
        (:func:`sketch_trajectory_encoder`) and ``E^2D_k`` (:class:`SketchKeyposeEncoder`)
        of Sec. 5 (attributes ``sketch_traj_encoder``, ``sketch_keypose_encoder``; trained by
        ``physlab.motion.train --stage align`` with everything else frozen). A condition dict
        with ``trajectory_2d`` / ``keypose_2d`` (:func:`check_condition`) is then encoded by
        them instead of the 3D encoders (:meth:`condition_embeddings`).
    """

    def __init__(self, base: MotionDenoiser, single_controlnet=False, traj_encoder=None,
                 keypose_encoder=None, sketch_encoders=False, double_controlnet=False,
                 control_head=False):
        super().__init__()
        if single_controlnet and double_controlnet:
            raise ValueError("single_controlnet and double_controlnet are two different Table 2 "
                             "ablations; set at most one")
        self.config = base.config
        self.single_controlnet = bool(single_controlnet)
        self.double_controlnet = bool(double_controlnet)
        self.base = base
        for p in self.base.parameters():
            p.requires_grad_(False)
        if self.single_controlnet:
            enc = traj_encoder or FrameConditionEncoder(4 * N_TRAJ + 3 * N_JOINTS + 1,
                                                        base.config)
            self.controlnet = TrajectoryControlNet(base, enc)
            self.adapter = None
        else:
            self.controlnet = TrajectoryControlNet(base, traj_encoder)
            self.adapter = KeyposeAdapter(base, keypose_encoder)
        if not (self.single_controlnet or self.double_controlnet):
            # The ControlNet's residuals reach the output only through the adapter's zero
            # layers Z'. With the ControlNet's own Z_i zero too, the gradient of each factor
            # is proportional to the other (both 0 at the start), so the trajectory branch
            # only starts learning once Z' has grown. Small random Z_i keep the controlled
            # model equal to the base at initialisation (Z' = 0) and let both learn at once.
            g = torch.Generator().manual_seed(0)
            with torch.no_grad():
                for z in self.controlnet.zero:
                    z.weight.normal_(0.0, CONTROLNET_INIT_STD / math.sqrt(z.in_features),
                                     generator=g)
        self.control_head = None
        if control_head:
            self.control_head = nn.Sequential(
                nn.LayerNorm(self.config.d_model),
                _zero_linear(self.config.d_model, self.config.feature_dim))
        self.base.eval()
        self.sketch_traj_encoder = self.sketch_keypose_encoder = None
        if sketch_encoders:
            self.add_sketch_encoders()

    @property
    def variant(self):
        """The Table 2 variant: ``"adapter"``, ``"single"`` or ``"double"``
        (:func:`controlnet_variant`)."""
        return controlnet_variant(self)

    def add_sketch_encoders(self):
        """Build untrained 2D encoders ``E^2D_tr`` and ``E^2D_k`` (Sec. 5); returns them."""
        if self.variant != "adapter":
            raise ValueError(f"the {controlnet_variant_label(self.variant)} ablation has no 2D "
                             f"encoders; align the ControlNet + adapter model")
        self.sketch_traj_encoder = sketch_trajectory_encoder(self.config)
        self.sketch_keypose_encoder = SketchKeyposeEncoder(self.config)
        return self.sketch_traj_encoder, self.sketch_keypose_encoder

    @property
    def has_sketch_encoders(self):
        return self.sketch_traj_encoder is not None

    def condition_embeddings(self, cond):
        """``(e_tr, e_k)``: the trajectory embedding (B, T, C) and the keypose embedding
        (B, C) of a condition dict — from the 3D encoders ``E_tr``, ``E_k`` or, for the 2D
        entries ``trajectory_2d`` / ``keypose_2d`` when given, from the aligned 2D encoders
        (which see ``camera``). These are the ``s^3D`` / ``s^2D`` of Eqs. (10) and (12)."""
        if self.single_controlnet:
            raise ValueError("the single-ControlNet ablation encodes its unified condition "
                             "matrix in one piece; condition_embeddings is for the "
                             "ControlNet + adapter model")
        sketch = "trajectory_2d" in cond or "keypose_2d" in cond
        if sketch and not self.has_sketch_encoders:
            raise ValueError("this model has no 2D encoders (train them with `python -m "
                             "physlab.motion.train --stage align`); give 3D conditions or "
                             "draw through the inference guidance")
        if "trajectory_2d" in cond:
            e_tr = self.sketch_traj_encoder(sketch_trajectory_frames(
                cond["trajectory_2d"], cond["traj_mask_2d"], cond["camera"]))
        else:
            e_tr = self.controlnet.cond_encoder(trajectory_frames(cond["trajectory"],
                                                                  cond["traj_mask"]))
        if "keypose_2d" in cond:
            e_k = self.sketch_keypose_encoder(cond["keypose_2d"], cond["key_frame"],
                                              cond["camera"])
        else:
            e_k = self.adapter.keypose_encoder(cond["keypose"], cond["key_frame"])
        return e_tr, e_k

    def branch_embeddings(self, cond, batch):
        """What the branches add to their tokens: ``(e_tr, e_k)`` — the unified condition
        embedding and None for the single-ControlNet ablation, else ``cond["embeddings"]``
        when the sampler made them once per clip (checked), or :meth:`condition_embeddings`.
        Shared by :meth:`forward` and :class:`FusedControlledDenoiser`."""
        if self.single_controlnet:
            frames = unified_frames(cond["trajectory"], cond["traj_mask"], cond["keypose"],
                                    cond["key_frame"], cond.get("keypose_mask"))
            return self.controlnet.cond_encoder(frames), None
        if "embeddings" in cond:
            return self._given_embeddings(cond, batch)
        return self.condition_embeddings(cond)

    def _given_embeddings(self, cond, batch):
        """``cond["embeddings"]`` checked: ``(e_tr (B, T, C), e_k (B, C))``."""
        emb = cond["embeddings"]
        C, T = self.config.d_model, self.config.n_frames
        shapes = [tuple(getattr(e, "shape", ())) for e in emb] if isinstance(emb, (tuple, list)) \
            else None
        if shapes != [(batch, T, C), (batch, C)]:
            raise ValueError(f"cond['embeddings'] must be the pair condition_embeddings(cond) "
                             f"returns, shapes [{(batch, T, C)}, {(batch, C)}], got "
                             f"{shapes if shapes is not None else type(emb).__name__}")
        return emb

    def train(self, mode=True):
        super().train(mode)
        self.base.eval()                                   # the frozen base never drops out
        return self

    def forward(self, x_t, t, text_emb, cond, drop_text=None):
        """Network output ``(B, T, D)`` (x̂₀ / ε̂ / v̂, as for :class:`MotionDenoiser`) for noisy features ``x_t`` (B, T, D), timesteps ``t`` (B,),
        action embeddings ``text_emb`` (B, text_dim) and a condition dict (see
        :func:`check_condition`). ``cond`` may carry ``"embeddings"``: the pair
        :meth:`condition_embeddings` returns for it, made once per clip by the sampler (the
        conditions stay the same at every denoising step; the ControlNet + adapter model only).
        :class:`FusedControlledDenoiser` computes the same for inference: keep the two in step."""
        _check_inputs(x_t, t, text_emb, self.config, drop_text)
        check_condition(cond, x_t.shape[0], self.config.n_joint_frames)
        km = cond.get("keypose_mask")
        e_tr, e_k = self.branch_embeddings(cond, x_t.shape[0])
        if self.single_controlnet:
            res, hidden = self.controlnet.from_embedding(x_t, t, text_emb, e_tr, drop_text,
                                                         with_hidden=True)
        else:
            r, h_r = self.controlnet.from_embedding(x_t, t, text_emb, e_tr, drop_text,
                                                    with_hidden=True)
            if self.double_controlnet:                     # two parallel ControlNets: r + r'
                rk, h_k = self.adapter.from_embedding(x_t, t, text_emb, e_k, None, drop_text,
                                                      keypose_mask=km, with_hidden=True)
                res, hidden = [u + v for u, v in zip(r, rk)], h_r + h_k
            else:
                res, hidden = self.adapter.from_embedding(x_t, t, text_emb, e_k, r, drop_text,
                                                          keypose_mask=km,
                                                          with_hidden=True)  # r'
        extra = None if self.control_head is None else self.control_head(hidden[:, 1:])
        return self.base(x_t, t, text_emb, drop_text, residuals=res,
                         out_extra=extra)                                   # Eq. (4)


# ----------------------------------------------------------------------------- fused inference


class StackedBlocks:
    """Block ``i`` of ``S`` same-shaped encoders run as one batched computation, for inference.

    A controlled denoising step runs three encoders (ControlNet copy, adapter copy, base)
    whose block ``i`` reads only block ``i - 1`` of the same encoder: the residuals are added
    *after* a block (:meth:`DenoiserEncoder.run_blocks`), so the ``S`` blocks of one depth can
    run side by side. Here they run as one: the weights are stacked ``(S, ...)`` and every
    linear layer is one :func:`torch.baddbmm`, so each operator is launched once instead of
    ``S`` times (at batch 1 a block of this size is small enough for launches to matter).

    The same arithmetic as :class:`Block` in eval mode (dropout off), to float rounding. The
    weights are copied at construction (:meth:`stale` says when the blocks' weights have
    changed since).

    Parameters
    ----------
    blocks : non-empty sequence of :class:`Block`, all with the same widths, head count,
        LayerNorm eps and GELU.
    """

    def __init__(self, blocks):
        blocks = list(blocks)
        if not blocks:
            raise ValueError("StackedBlocks needs at least one Block")
        first = blocks[0]

        def signature(b):
            return (b.attn.n_heads, tuple(b.mlp[0].weight.shape), b.ln1.eps, b.ln2.eps,
                    b.mlp[1].approximate)

        if any(signature(b) != signature(first) for b in blocks):
            raise ValueError(f"StackedBlocks needs blocks of one kind (n_heads, (ff, d_model), "
                             f"LayerNorm eps, GELU): got {[signature(b) for b in blocks]}")
        self.n_stacked = len(blocks)
        self.n_heads = first.attn.n_heads
        self.eps = (first.ln1.eps, first.ln2.eps)
        self.gelu = first.mlp[1].approximate
        self._params = [p for b in blocks for p in b.parameters()]
        self._versions = [p._version for p in self._params]

        def stack(get, transpose=False):
            ts = [get(b).detach() for b in blocks]
            return torch.stack([t.T if transpose else t for t in ts]).contiguous()

        # plain tensors even when built under torch.inference_mode(): the network-space
        # guidance later differentiates through them
        with torch.inference_mode(False), torch.no_grad():
            self.ln = [(stack(lambda b, n=n: getattr(b, n).weight)[:, None, None],
                        stack(lambda b, n=n: getattr(b, n).bias)[:, None, None])
                       for n in ("ln1", "ln2")]                          # (S, 1, 1, C) each
            linears = {"qkv": lambda b: b.attn.qkv, "proj": lambda b: b.attn.proj,
                       "fc1": lambda b: b.mlp[0], "fc2": lambda b: b.mlp[2]}
            self.w = {k: stack(lambda b, f=f: f(b).weight, transpose=True)  # (S, in, out)
                      for k, f in linears.items()}
            self.b = {k: stack(lambda b, f=f: f(b).bias)[:, None]        # (S, 1, out)
                      for k, f in linears.items()}

    def stale(self):
        """True when a weight of the blocks changed after construction (an optimiser step,
        ``load_state_dict``, any in-place write: each bumps the tensor's version counter)."""
        return any(p._version != v for p, v in zip(self._params, self._versions))

    def _linear(self, name, x):                                            # (S, M, in)
        return torch.baddbmm(self.b[name], x, self.w[name])               # (S, M, out)

    def __call__(self, h):
        """``h`` (S, B, L, C): the inputs of the ``S`` blocks -> their outputs (S, B, L, C)."""
        S, B, L, C = h.shape
        H = self.n_heads
        (g1, b1), (g2, b2) = self.ln
        x = F.layer_norm(h, (C,), eps=self.eps[0]) * g1 + b1
        q, k, v = self._linear("qkv", x.reshape(S, B * L, C)).split(C, dim=2)
        q, k, v = (u.reshape(S * B, L, H, C // H).transpose(1, 2) for u in (q, k, v))
        att = (q @ k.transpose(-2, -1)) / math.sqrt(k.shape[-1])         # (S B, H, L, L)
        y = (att.softmax(dim=-1) @ v).transpose(1, 2).reshape(S, B * L, C)
        h = h + self._linear("proj", y).view(S, B, L, C)
        x = F.layer_norm(h, (C,), eps=self.eps[1]) * g2 + b2
        m = F.gelu(self._linear("fc1", x.reshape(S, B * L, C)), approximate=self.gelu)
        return h + self._linear("fc2", m).view(S, B, L, C)


class FusedControlledDenoiser:
    """:meth:`ControlledDenoiser.forward` for inference, with the blocks of one depth of all
    its encoders run as one :class:`StackedBlocks`: the same call and the same output, to
    float rounding. A networks-only clip takes 0.66–0.84x the time of the plain forward on one
    thread of a 2-core AVX2 EPYC (``benchmarks/bench_motion.py``, the row "encoders one after
    the other").

    The sampler (:class:`~physlab.motion.sampling.Generator`) runs one per controlled
    checkpoint. The block weights are stacked copies, re-made at the next call whenever a
    block weight has changed (:meth:`StackedBlocks.stale`); everything else (condition
    encoders, token layers, zero layers, head, the sampler's low-pass settings) is read from
    ``model`` at each call. Gradients flow to the inputs (the network-space guidance needs
    them), not to the stacked copies. Keep :meth:`__call__` in step with
    :meth:`ControlledDenoiser.forward`.

    Parameters
    ----------
    model : :class:`ControlledDenoiser` in eval mode (dropout off), any Table 2 variant.
    """

    def __init__(self, model: ControlledDenoiser):
        if not isinstance(model, ControlledDenoiser):
            raise TypeError(f"model must be a ControlledDenoiser, got {type(model).__name__}")
        if any(m.training for m in model.modules()):
            raise ValueError("FusedControlledDenoiser is for inference: call model.eval() first "
                             "(it has no dropout)")
        self.model = model
        self.config = model.config
        self._stack()

    def _stack(self):
        m = self.model
        encoders = [m.controlnet.encoder] + ([m.adapter.encoder] if m.adapter is not None
                                             else []) + [m.base.encoder]
        self.layers = [StackedBlocks([e.blocks[i] for e in encoders])
                       for i in range(len(m.base.encoder.blocks))]

    def __repr__(self):
        return (f"FusedControlledDenoiser(variant={self.model.variant!r}, "
                f"encoders={self.layers[0].n_stacked}, layers={len(self.layers)})")

    def __call__(self, x_t, t, text_emb, cond, drop_text=None):
        """As :meth:`ControlledDenoiser.forward`: ``x_t`` (B, T, D), ``t`` (B,), ``text_emb``
        (B, text_dim), a condition dict, ``drop_text`` None or (B,) bool -> (B, T, D)."""
        m = self.model
        _check_inputs(x_t, t, text_emb, self.config, drop_text)
        check_condition(cond, x_t.shape[0], self.config.n_joint_frames)
        if any(layer.stale() for layer in self.layers):
            self._stack()
        km = cond.get("keypose_mask")
        cn, ad, base = m.controlnet, m.adapter, m.base
        e_tr, e_k = m.branch_embeddings(cond, x_t.shape[0])
        tokens = [cn.encoder.tokens(x_t, t, text_emb, drop_text, motion_extra=e_tr)]
        if not m.single_controlnet:
            if km is not None:                                             # no keypose: a' = a
                e_k = e_k * km.to(e_k.dtype)[:, None]
            tokens.append(ad.encoder.tokens(x_t, t, text_emb, drop_text, cond_extra=e_k))
        tokens.append(base.encoder.tokens(x_t, t, text_emb, drop_text))
        h = torch.stack(tokens)                                            # (S, B, 1+T, C)
        for i, layer in enumerate(self.layers):
            h = layer(h)                                                   # (S, B, 1+T, C)
            r = cn.zero[i](h[0])                                           # Eq. (1): r_i
            if m.single_controlnet:
                h = torch.stack([h[0], h[1] + r])
                hidden = h[0]
            elif m.double_controlnet:                                      # r_i + r'_i
                h = torch.stack([h[0], h[1], h[2] + r + ad.zero[i](h[1])])
                hidden = h[0] + h[1]
            else:                                                          # Eq. (3), then (4)
                h_k = h[1] + r
                h = torch.stack([h[0], h_k, h[2] + ad.zero[i](h_k)])
                hidden = h_k
        extra = None if m.control_head is None else m.control_head(hidden[:, 1:])
        return base.output(h[-1], x_t, t, extra)
