"""Training of the motion generator: stage ``base`` (text-conditioned denoiser, Sketch2Anim's
pre-trained MLD stand-in) and stage ``control`` (trajectory ControlNet + keypose adapter on
the frozen base, Sketch2Anim Sec. 4.3, Eqs. (5)–(9)).

Run::

    python -m physlab.motion.train --stage base --steps 4000 --out runs/base.pt
    python -m physlab.motion.train --stage control --base-ckpt runs/base.pt --steps 4000 \\
        --out runs/control.pt
    torchrun --nproc_per_node=2 -m physlab.motion.train --stage base ...   # DDP, gloo
    python -m physlab.motion.train --stage base --smoke --out /tmp/smoke.pt # seconds

On 2 CPU cores with the default model (batch 64, one process, 2 threads) the base stage
runs at ~400–450 windows/s (~6.5 steps/s: 4000 steps ≈ 10 min) and the control stage at
~145 windows/s (~2.2 steps/s: 4000 steps ≈ 30 min); ``torchrun`` with two 1-thread
processes was not faster (~380 / ~130 windows/s). There are 1807 training windows (take 001,
stride 10).

**What the network predicts** (``--prediction``, stored in the checkpoint's scheduler):
Sketch2Anim (like MLD) trains ε-prediction, L_recon = ‖ε − ε̂‖² (Eq. (5)), and gets x̂₀ for
L_tr / L_key from Eq. (7). MLD denoises a compact VAE latent; physlab denoises the 137-d
features directly, and there ε-prediction failed: a default-size model trained 8000 steps
with ``--prediction epsilon`` ignored the action text (root travel over 2 s: walks 0.37 m,
bows 0.37 m, walks backwards +0.41 m; real clips: +1.95, 0.0, −1.3 m) and produced broken
bodies (wrists up to 3.5 m above the head), because at the noisy steps that fix the global
motion, x̂₀ = (x_t − √(1−ᾱ_t) ε̂)/√ᾱ_t amplifies ε errors ~15x (√ᾱ_T ≈ 0.068) and the
ε-loss weights x₀ errors by the SNR, i.e. almost not at all there. The default is
therefore MDM's choice (Tevet et al. 2023, Sec. 3): the network predicts x₀ ("sample");
the loss of Eq. (5) is taken on that output, and x̂₀ of Eq. (7) is the output itself
(:meth:`~physlab.motion.diffusion.NoiseScheduler.split_output` gives x̂₀ and ε̂ for any
parametrisation, so sampling, DDIM and classifier-free guidance are unchanged). After 1500
steps the x₀ model already follows the text (walks +5.0 m, bows −0.3 m, walks backwards
−2.0 m, with w = 7.5). ``--prediction epsilon`` reproduces the paper's parametrisation.

**Velocity loss** (``--lambda-vel``, default 1, both stages): x₀-prediction alone gave
jittery clips (mean |second difference| of the joints over 3 seeds, 50 DDIM steps, w = 7.5,
base trained 4000 steps: walks 0.093 m/frame², walks backwards 0.020; real Bandai walks:
0.0055). MDM's ``L_vel`` (Tevet et al. 2023, Eq. (4)), here on the feature rows
(:func:`velocity_loss`), brings them to 0.038 and 0.009 with the same text adherence
(walks +3.4 m, walks backwards −2.0 m, bows −0.1 m over the 2 s clip).

**Representation** (``--representation``, default ``"absolute"`` for a new base): the first
shipped models denoised HumanML3D-style ``"relative"`` rows (root velocities, root-relative
joints; :mod:`~physlab.motion.features`), as Sketch2Anim does. Their ControlNet and adapter
did react to the conditions — on held-out windows one denoising step of the control model
halved L_tr of x̂₀ against the base (0.018 -> 0.009 m² at t = 50, 0.081 -> 0.044 m² at
t = 900) — but sampled clips ended as far from the targets as text-only ones (0.43 m): the
pelvis path is the cumulative sum of 39 predicted velocities, so small per-row errors add
up to a drift that no single row can see, and the ~50-step sampler compounds them. In the
``"absolute"`` rows (pelvis position + pelvis-relative joints per frame,
:func:`~physlab.motion.features.joints_to_absolute_features`) a trajectory point at frame
``i`` is a function of row ``i`` alone, which is what a per-frame ControlNet input can
learn; Meng et al. 2025 ("Absolute Coordinates Make Motion Generation Easy") report the
same for text- and control-conditioned diffusion. Both representations remain trainable.

**Conditions in training** (``--drop-keypose``, ``--drop-trajectory``): 10 % of the
control-stage samples have no keypose and 10 % no trajectory, so any subset of conditions
is in-distribution at inference (``keypose_mask`` of the condition dict).

Every flag is a field of :class:`TrainConfig` or :class:`~physlab.motion.model.DenoiserConfig`
(``--d-model 128`` …), and :func:`train` takes the same names as keyword arguments.

A checkpoint (``torch.save`` dict, written atomically) holds everything needed to generate
and to resume: ``stage``, ``model_config``, ``train_config``, ``model`` (state dict; for the
control stage the whole :class:`ControlledDenoiser`, frozen base included), ``optimizer``,
``step``, per-rank ``rng`` states, ``feature_stats`` (mean / std), ``scheduler``
(:meth:`NoiseScheduler.to_dict`), ``text_cache`` (:meth:`EmbeddingCache.state_dict`, so known
action texts never need the text encoder) and ``param_digests`` (one sha256 of the
parameters per DDP rank). :func:`load_model` rebuilds the network from it;
:func:`export_weights` writes an inference-only copy (no optimizer, fp16 by default).
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch


from .dataset import (
    TEST_TAKES,
    action_text,
    load_clips,
    make_windows,
    mirror_windows,
    random_condition,
    read_labels,
    split_by_take,
    turn_windows,
)
from .diffusion import PREDICTION_TYPES, NoiseScheduler, SchedulerConfig
from .features import ABS_PATH, FeatureStats, encode_motion
from .model import (
    ControlledDenoiser,
    DenoiserConfig,
    MotionDenoiser,
    controlnet_variant,
    controlnet_variant_label,
    count_parameters,
)
from .skeleton import JOINT_NAMES
from .checkpoint import (CHECKPOINT_KIND, CHECKPOINT_VERSION, NOTHING_LEFT_TO_TRAIN,  # noqa: F401
                         export_weights, has_control_head, load_checkpoint, load_model,
                         save_checkpoint)
from .align import alignment_losses, camera_projections, sketch_batch
from .guidance import control_losses, projected_trajectory_loss  # noqa: F401 - API
from .text import hash_encoder  # noqa: F401 - part of this module's API

__all__ = [
    "SCHEDULERS",
    "PRECISIONS",
    "SMOKE_MODEL",
    "TrainConfig",
    "action_weights",
    "condition_batch",
    "recon_loss",
    "control_losses",
    "export_weights",
    "hash_encoder",
    "load_checkpoint",
    "load_model",
    "main",
    "native_bf16",
    "prepare_data",
    "training_windows",
    "save_checkpoint",
    "train",
    "warmup_cosine_lr",
]

#: Noise schedules by name. "mld": MLD's (Chen et al. 2023) scaled-linear schedule
#: (sqrt(ᾱ_T) ≈ 0.068, so x̂₀ of Eq. (7) is amplified at most ~15x at the noisiest step in
#: L_tr / L_key); "ddpm": Ho et al.'s linear 1e-4..0.02 (sqrt(ᾱ_T) ≈ 0.006).
SCHEDULERS = {
    "mld": {"beta_start": 0.00085, "beta_end": 0.012, "beta_schedule": "scaled_linear",
            "set_alpha_to_one": False, "steps_offset": 1},
    "ddpm": {},
}

#: Representation of a new base stage (``--representation``); see the module docstring.
DEFAULT_REPRESENTATION = "absolute"

#: DCT frequencies kept in x̂₀ by a new absolute base (``--smooth-basis``; module docstring).
DEFAULT_SMOOTH_BASIS = 16

#: Training stages: the text denoiser, its ControlNet + keypose adapter, the 2D encoders.
STAGES = ("base", "control", "align")
#: ``--precision`` choices: float32 throughout, the forward passes in bfloat16 autocast, or
#: ``"auto"``: bf16 where the CPU computes bfloat16 natively (:func:`native_bf16`), else fp32.
PRECISIONS = ("fp32", "bf16", "auto")
#: Model of ``--smoke`` runs: a few seconds on a CPU.
SMOKE_MODEL = {"d_model": 32, "n_heads": 2, "n_layers": 2, "ff": 64, "dropout": 0.0}


@dataclass
class TrainConfig:
    """Training settings; saved in the checkpoint."""

    stage: str = "base"             # "base" (text denoiser) | "control" (ControlNet + adapter)
                                    # | "align" (2D encoders of Sec. 5, on a control checkpoint)
    out: str = ""                   # checkpoint path (atomic, rank 0); "" = runs/<stage>.pt
                                    # (runs/smoke_<stage>.pt with --smoke)
    base_ckpt: str = ""             # control stage: the trained base checkpoint (or a control
                                    # checkpoint: its frozen base)
    resume: bool = True             # continue from `out` if it exists
    seed: int = 0                   # seeds data order, noise, dropout (rank r uses seed + r)
    steps: int = 6000               # optimiser steps in total (resume continues up to it)
    batch_size: int = 64            # windows per step and rank
    lr: float = 2e-4                # peak AdamW learning rate (paper: 1e-5 over 12 GPU hours)
    min_lr: float = 2e-5            # cosine decay floor
    warmup: int = 200               # linear warm-up steps
    weight_decay: float = 0.01      # AdamW weight decay
    grad_clip: float = 1.0          # max global gradient norm (0 = off)
    lambda_tr: float = 1.0          # λ_tr of Eq. (9) (paper: all weights 1)
    lambda_key: float = 1.0         # λ_key of Eq. (9)
    lambda_vel: float = 1.0         # MDM's velocity loss on x̂₀ (module doc); 0 = off
    cond_drop_prob: float = -1.0    # p(text dropped) for CFG; < 0: the model config's value
    min_t_r: int = 5                # shortest trajectory (frames) of a random condition
    drop_keypose: float = 0.1       # p(no keypose) in a control-stage condition (trajectories
                                    # only), so any subset of conditions can be given
    drop_trajectory: float = 0.1    # p(no trajectory) (keypose only); never both
    single_joint: float = 0.0       # extra p(a single-joint stroke) in a random condition
                                    # (the "Average" protocol's kind; uniform: 6/63)
    single_controlnet: bool = False  # Table 2 ablation: one ControlNet for both conditions
    double_controlnet: bool = False  # Table 2 ablation: keypose ControlNet beside the
                                    # trajectory one (residuals added), not an adapter on it
    control_head: bool = False      # control stage: a zero-initialised head on the adapter's
                                    # last block added to x̂₀ after the base's skip connection
                                    # (ControlledDenoiser, control_head); not in the paper
    direct_2d: bool = False         # control stage on drawn (projected) conditions through 2D
                                    # encoders from the start: Table 1's direct 2D baseline
    lambda_match: float = 1.0       # align stage, Eq. (13): weight of L_match (Eq. 10; 0 = off)
    lambda_recon: float = 1.0       # λ_r: weight of L_recon (Eq. 11; 0 = off, and cheaper)
    lambda_contrast: float = 1.0    # λ_c: weight of L_contrast (Eq. 12; 0 = off)
    lambda_tr_2d: float = 0.0       # align stage: weight of the drawn trajectories' error of
                                    # the decoded x̂₀ in the drawing's view (Eq. (16)'s G as a
                                    # training term, depth-free); 0 = off
    tau: float = 0.1                # τ₁ of Eq. (12)
    sketch_noise: float = 0.02      # align stage: joint noise of the drawings (supp. B)
    scheduler: str = "mld"          # noise schedule, a key of SCHEDULERS
    prediction: str = "sample"      # network output: "sample" (x0, MDM; default) |
                                    # "epsilon" (Sketch2Anim) | "v_prediction"; module doc
    checkpoint_every: int = 500     # steps between checkpoints (and at the end)
    precision: str = "fp32"         # "fp32" | "bf16": the networks' forward passes under
                                    # torch.autocast(bfloat16) (weights, optimiser and losses
                                    # stay float32); 1.2-1.4x faster on CPUs with AVX512-BF16,
                                    # ~30x slower without | "auto": bf16 if native_bf16()
    num_threads: int = 0            # torch threads per process; 0 = cores / processes
    data_root: str = ""             # Bandai-Namco folder; "" = <external data>/mocap/bandai_namco
    max_clips: int = 0              # use only the first k training clips (0 = all)
    window_stride: int = 10         # frames between window starts (40-frame windows)
    mirror: bool = False            # add every window's mirror image (dataset.mirror_windows)
    turn_augment: float = 0.0       # > 0: add a copy of every window turned progressively by
                                    # up to this many degrees (dataset.turn_windows); 0 = off
    snr_cap: float = 0.0            # > 0: weight each window's x0 loss by min(1/(1 − ᾱ_t), cap)
                                    # (recon_loss; with --skip); 0 = plain x0 MSE
    balance: float = 0.0            # draw a window with weight (windows of its action)^-balance:
                                    # 0 = uniform, 1 = every action equally often (action_weights)
    style_drop: float = 0.0         # p(a window's style adverb is dropped): it is trained with
                                    # its action's plain text ("a person walks backwards"), which
                                    # then means the action in any style, as a storyboard's bare
                                    # action word does; 0 = off: the plain text is trained on the
                                    # "normal" style's windows only (none for some actions)
    pelvis_scale: float = 1.0       # "absolute" features: the pelvis x and z are normalised
                                    # by their std / this (a fresh run's statistics; the
                                    # checkpoint keeps them): > 1 makes a noise level that many
                                    # times smaller in metres on the path, so a near-still
                                    # action's sway is seen (docs/motion_experiments.md)
    pelvis_loss_weight: float = 1.0  # stage base: weight of the pelvis x and z columns in the
                                    # reconstruction and velocity losses; with pelvis_scale F,
                                    # 1 / F**2 gives the path the loss weight it has at F = 1
    text_encoder: str = "minilm"    # "minilm" (text.ActionEncoder) | "hash" (tests: fake)
    text_cache: str = ""            # optional EmbeddingCache .npz to read / fill
    smoke: bool = False             # tiny model, few steps, few clips: seconds
    progress: bool = True           # tqdm bar on rank 0

    def __post_init__(self):
        for name in ("out", "base_ckpt", "data_root", "text_cache"):   # a Path is welcome, but
            if isinstance(getattr(self, name), os.PathLike):         # the checkpoint stores str
                setattr(self, name, os.fspath(getattr(self, name)))
        if self.precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}, got {self.precision!r} "
                             f"(bf16 runs the forward passes in bfloat16 autocast; auto picks "
                             f"bf16 where the CPU has native bfloat16, else fp32)")
        if self.precision == "auto":                     # the checkpoint records what ran
            self.precision = "bf16" if native_bf16() else "fp32"
        if self.stage not in STAGES:
            raise ValueError(f"stage must be one of {STAGES}, got {self.stage!r}")
        if self.scheduler not in SCHEDULERS:
            raise ValueError(f"scheduler must be one of {sorted(SCHEDULERS)}, got "
                             f"{self.scheduler!r}")
        if self.prediction not in PREDICTION_TYPES:
            raise ValueError(f"prediction must be one of {PREDICTION_TYPES}, got "
                             f"{self.prediction!r}")
        if self.text_encoder not in ("minilm", "hash"):
            raise ValueError(f"text_encoder must be 'minilm' or 'hash', got "
                             f"{self.text_encoder!r}")
        for name in ("steps", "batch_size", "checkpoint_every", "min_t_r", "window_stride"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("lr", "min_lr", "weight_decay", "grad_clip", "lambda_tr", "lambda_key",
                     "lambda_vel", "warmup", "seed", "num_threads", "max_clips",
                     "cond_drop_prob", "drop_keypose", "drop_trajectory", "single_joint",
                     "lambda_match",
                     "lambda_recon", "lambda_contrast", "lambda_tr_2d", "tau", "sketch_noise",
                     "balance", "snr_cap", "turn_augment", "pelvis_scale",
                     "pelvis_loss_weight"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
        if not 0.1 <= self.pelvis_scale <= 100:
            raise ValueError(f"pelvis_scale must be in [0.1, 100] (1 = the data's std; e.g. 4), "
                             f"got {self.pelvis_scale}")
        if not 0 < self.pelvis_loss_weight <= 100:
            raise ValueError(f"pelvis_loss_weight must be in (0, 100] (1 = as every other "
                             f"column; e.g. 1 / pelvis_scale**2), got {self.pelvis_loss_weight}")
        if not 0 <= self.turn_augment <= 180:
            raise ValueError(f"turn_augment must be in [0, 180] degrees (0 = off; e.g. 90), got "
                             f"{self.turn_augment}")
        if not 0 < self.lr <= 1:
            raise ValueError(f"lr must be in (0, 1] (AdamW; the default is 2e-4), got {self.lr}")
        if not 0 <= self.min_lr <= self.lr:
            raise ValueError(f"min_lr must be in [0, lr = {self.lr}], got {self.min_lr}")
        for name in ("weight_decay", "grad_clip", "lambda_tr", "lambda_key", "lambda_vel",
                     "lambda_tr_2d", "warmup", "max_clips"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0 <= self.seed < 2**63:
            raise ValueError(f"seed must be an integer in [0, 2**63), got {self.seed}")
        if not 0 <= self.num_threads <= 256:
            raise ValueError(f"num_threads must be in 0..256 (0 = automatic), got "
                             f"{self.num_threads}")
        if self.snr_cap and not (self.snr_cap >= 1 and self.prediction == "sample"):
            raise ValueError(f"snr_cap must be 0 (off) or >= 1 with --prediction sample (it "
                             f"weights the x0 loss), got {self.snr_cap} with --prediction "
                             f"{self.prediction}")
        if not (math.isfinite(self.style_drop) and 0 <= self.style_drop <= 1):
            raise ValueError(f"style_drop must be a probability in [0, 1] (0 = off), got "
                             f"{self.style_drop!r}")
        if not 0 <= self.balance <= 1:
            raise ValueError(f"balance must be in [0, 1] (0 = uniform sampling, 1 = every "
                             f"action equally often), got {self.balance}")
        if not 0 <= self.single_joint <= 1:
            raise ValueError(f"single_joint must be a probability in [0, 1], got "
                             f"{self.single_joint}")
        if not (0 <= self.drop_keypose and 0 <= self.drop_trajectory
                and self.drop_keypose + self.drop_trajectory <= 1):
            raise ValueError(f"drop_keypose and drop_trajectory must be >= 0 with a sum <= 1, "
                             f"got {self.drop_keypose} and {self.drop_trajectory}")
        if not math.isfinite(self.cond_drop_prob) or self.cond_drop_prob > 1:
            raise ValueError(f"cond_drop_prob must be <= 1 (< 0: the model config's value), got "
                             f"{self.cond_drop_prob}")
        if self.steps > 10_000_000:
            raise ValueError(f"steps must be <= 10,000,000, got {self.steps}")
        if self.stage == "control" and not self.base_ckpt:
            raise ValueError("stage 'control' needs --base-ckpt <checkpoint of stage 'base'>")
        if self.single_controlnet and self.double_controlnet:
            raise ValueError("--single-controlnet and --double-controlnet are two Table 2 "
                             "ablations; give at most one")
        if (self.single_controlnet or self.double_controlnet) and self.stage != "control":
            raise ValueError("--single-controlnet / --double-controlnet are variants of "
                             "--stage control")
        if self.control_head and self.stage != "control":
            raise ValueError("--control-head is a part of the ControlNet stage: use it with "
                             "--stage control (align reads it from --base-ckpt)")
        if self.direct_2d and (self.stage != "control" or self.single_controlnet
                               or self.double_controlnet):
            raise ValueError("--direct-2d trains the ControlNet + adapter stage on drawn "
                             "conditions: use it with --stage control, without "
                             "--single-controlnet or --double-controlnet")
        if self.stage == "align" and not self.base_ckpt:
            raise ValueError("stage 'align' needs --base-ckpt <checkpoint of stage 'control'> "
                             "(the generator whose 3D encoders the 2D ones learn to match)")
        for name in ("tau",):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("lambda_match", "lambda_recon", "lambda_contrast", "sketch_noise"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.stage == "align" and not (self.lambda_match or self.lambda_recon
                                          or self.lambda_contrast):
            raise ValueError("stage 'align' needs at least one of --lambda-match, "
                             "--lambda-recon, --lambda-contrast > 0")
        if self.lambda_tr_2d and (self.stage != "align" or not self.lambda_recon):
            raise ValueError(f"--lambda-tr-2d {self.lambda_tr_2d} is a term of L_recon in stage "
                             f"'align' (the pass through the frozen generator): use it with "
                             f"--stage align and --lambda-recon > 0, or leave it at 0")


# ----------------------------------------------------------------------------- data


def _text_cache(texts, cfg: TrainConfig):
    from .text import ActionEncoder, EmbeddingCache

    encoder = hash_encoder if cfg.text_encoder == "hash" else None
    if cfg.text_cache and Path(cfg.text_cache).is_file():
        cache = EmbeddingCache.load(cfg.text_cache)
    else:
        cache = EmbeddingCache()
    if any(t not in cache for t in texts):
        if encoder is None:
            encoder = ActionEncoder(num_threads=cfg.num_threads or None)
        cache.get(sorted(set(texts)), encoder=encoder)
        if cfg.text_cache:
            cache.save(cfg.text_cache)
    return cache


def native_bf16():
    """True if this CPU computes bfloat16 natively (AVX512-BF16 or AMX-BF16, as oneDNN sees
    it), so that ``--precision bf16`` pays off. Without it PyTorch emulates bfloat16 and the
    autocast forward passes are far slower than float32: on a 2-core AVX2-only AMD EPYC
    (2026-11-28) the base stage ran ~0.3 steps/s in bf16 against ~4.7 in fp32, where a host
    with AVX512-BF16 ran bf16 1.24x (base) / 1.36x (control) faster than fp32."""
    try:
        return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
    except (AttributeError, RuntimeError):              # a build without oneDNN: ask the CPU
        caps = getattr(torch._C._cpu, "_get_cpu_capability", dict)()
        return bool(caps.get("avx512_bf16") or caps.get("amx_bf16"))


def training_windows(data_root=None, max_clips=0, stride=10):
    """The 40-frame training windows (every Bandai-Namco take but the held-out 002, or the
    first ``max_clips`` training clips for quick runs) and the sorted list of their takes."""
    ids = None
    if max_clips:
        rows = [r for r in read_labels(data_root) if r["take"] not in TEST_TAKES]
        ids = [Path(r["file"]).stem for r in rows[:max_clips]]
    clips = load_clips(data_root, clip_ids=ids)
    train_clips, _ = split_by_take(clips) if ids is None else (clips, None)
    return (make_windows(train_clips, length=40, stride=stride),
            sorted({c.take for c in train_clips}))


def prepare_data(cfg: TrainConfig, stats: FeatureStats | None = None, cache=None,
                 representation="relative"):
    """Training windows as tensors.

    Loads the training clips (:func:`split_by_take`: every take but 002), cuts 40-frame
    windows (stride ``cfg.window_stride``), computes their features in ``representation``
    (:data:`~physlab.motion.features.REPRESENTATIONS`) and normalises them.

    Returns
    -------
    dict with ``x0`` (N, 39, 137) (relative) or (N, 40, 70) (absolute) float32 normalised
    features, ``joints`` (N, 40, 22, 3)
    float64 canonical windows, ``text_index`` (N,) int64 into ``text_emb`` (V, 384) float32,
    ``plain_index`` (N,) int64: the window's action text without its style adverb
    (``TrainConfig.style_drop``),
    ``texts`` (list of V str), ``stats`` (:class:`FeatureStats`, computed here unless given),
    ``cache`` (:class:`~physlab.motion.text.EmbeddingCache`), ``train_takes`` (sorted list of
    the Bandai-Namco takes trained on; stored in the checkpoint).
    """
    win, train_takes = training_windows(cfg.data_root or None, cfg.max_clips,
                                        cfg.window_stride)
    if cfg.mirror:
        win = mirror_windows(win)
    if cfg.turn_augment:
        win = turn_windows(win, cfg.turn_augment, seed=cfg.seed)
    feats = np.stack([encode_motion(w, representation, fps=win.fps)
                      for w in win.joints])                       # (N, 39, 137) | (N, 40, 70)
    if stats is None:
        stats = FeatureStats.from_features(feats, representation=representation)
        if cfg.pelvis_scale != 1:
            if representation != "absolute":
                raise ValueError(f"pelvis_scale {cfg.pelvis_scale} needs the 'absolute' "
                                 f"representation (its pelvis path columns), got "
                                 f"{representation!r}; use --pelvis-scale 1")
            stats.std[list(ABS_PATH)] /= cfg.pelvis_scale                   # x, z
    plain = [action_text(c) for c in win.content]            # the texts without a style adverb
    texts = sorted(set(win.text) | set(plain))
    if cache is None:
        cache = _text_cache(texts, cfg)
    E = cache.get(texts, encoder=hash_encoder if cfg.text_encoder == "hash" else None)
    index = {t: i for i, t in enumerate(texts)}
    return {"x0": torch.tensor(stats.normalize(feats), dtype=torch.float32),
            "joints": win.joints,
            "text_index": torch.tensor([index[t] for t in win.text], dtype=torch.int64),
            "plain_index": torch.tensor([index[t] for t in plain], dtype=torch.int64),
            "text_emb": torch.tensor(E, dtype=torch.float32), "texts": texts,
            "stats": stats, "cache": cache,
            "train_takes": train_takes,
            "sample_weights": torch.tensor(action_weights(win.content, cfg.balance),
                                           dtype=torch.float64)}


def recon_loss(out, target, t, scheduler, snr_cap=0.0, weights=None):
    """The denoising loss of Eq. (5) on the network output, optionally weighted per window.

    ``snr_cap = 0``: ``mean ‖out − target‖²``. ``snr_cap > 0`` (x₀-prediction): window ``b``'s
    squared error is weighted by ``min(1 / (1 − ᾱ_t), snr_cap) = min(SNR_t + 1, cap)``. With
    the skip connection (``DenoiserConfig.skip``: ``x̂₀ = √ᾱ x_t + √(1 − ᾱ) F``) the plain x₀
    loss weights ``F``'s error by ``1 − ᾱ_t``, almost nothing near t = 0, so the network never
    learns to cancel the noise that the skip lets through; ``1 / (1 − ᾱ_t)`` is EDM's weight
    ``1 / c_out²`` (the v-prediction loss), and the cap keeps the lowest levels from dominating,
    as Min-SNR-γ does (Hang et al. 2023, Eq. (8)). Weights are ≥ 1, so the noisiest levels keep
    the plain x₀ loss.

    out, target : (B, T, D); t : (B,) int64 levels; scheduler : NoiseScheduler.
    weights : None or (D,) tensor, each feature column's weight in the squared error
        (:func:`column_weights`).
    Returns a scalar tensor.
    """
    se = (out - target) ** 2
    if weights is not None:
        se = se * weights
    if not snr_cap:
        return se.mean()
    abar = scheduler.alphas_cumprod.to(out.dtype)[t]                        # (B,)
    w = torch.clamp(1.0 / (1.0 - abar), max=float(snr_cap))                 # (B,)
    return (w * se.mean(dim=(1, 2))).mean()


def column_weights(dim, pelvis_weight=1.0):
    """Per-column loss weights of the absolute features: 1, and ``pelvis_weight`` on the
    pelvis x and z columns (:data:`~physlab.motion.features.ABS_PATH`); None when all are 1.
    With ``pelvis_scale`` F those columns' errors are F times larger in units, so their
    squared error counts F² times as much as at F = 1; ``pelvis_weight = 1 / F²`` undoes that
    while keeping the finer noise on the path."""
    if pelvis_weight == 1:
        return None
    w = torch.ones(dim)
    w[list(ABS_PATH)] = float(pelvis_weight)
    return w


def action_weights(actions, balance=0.0):
    """Sampling weights of training windows that balance their actions.

    ``w_i = n(a_i)^-balance / Σ_j n(a_j)^-balance`` with ``n(a)`` the number of windows of
    action ``a``: ``balance = 0`` draws windows uniformly (an action as often as it has
    windows), ``balance = 1`` draws every action equally often, and values between soften
    the long tail (Bandai-Namco has 100 walk clips but 15 of walking backwards and one kick).

    Parameters
    ----------
    actions : sequence of N hashable action labels (e.g. ``Windows.content``).
    balance : float in [0, 1].

    Returns
    -------
    (N,) float64 array, positive, summing to 1.
    """
    if isinstance(balance, bool) or not isinstance(balance, (int, float)) \
            or not 0 <= balance <= 1:
        raise ValueError(f"balance must be a number in [0, 1], got {balance!r}")
    actions = list(actions)
    if not actions:
        raise ValueError("actions is empty: no training windows to weight")
    counts = {}
    for a in actions:
        counts[a] = counts.get(a, 0) + 1
    w = np.array([counts[a] ** -float(balance) for a in actions], dtype=np.float64)
    return w / w.sum()


def condition_batch(windows, rng, min_t_r=5, drop_keypose=0.0, drop_trajectory=0.0,
                    single_joint=0.0):
    """Random Sketch2Anim training conditions (:func:`random_condition`) of a batch.

    Parameters
    ----------
    windows : (B, 40, 22, 3) float array of canonical windows.
    rng : numpy Generator.
    min_t_r : shortest trajectory (frames); single_joint : extra share of single-joint
        strokes (:func:`~physlab.motion.dataset.random_condition`).
    drop_keypose, drop_trajectory : probabilities that a sample has no keypose (its
        ``keypose_mask`` is False) or no trajectory (its ``traj_mask`` is all False); the two
        events exclude each other, so every sample keeps a condition.

    Returns
    -------
    dict of tensors: ``trajectory`` (B, 40, 6, 3) float32, ``traj_mask`` (B, 40, 6) bool,
    ``keypose`` (B, 22, 3) float32, ``key_frame`` (B,) int64, ``keypose_mask`` (B,) bool.
    """
    w = np.asarray(windows, dtype=float)
    if w.ndim != 4 or w.shape[2:] != (len(JOINT_NAMES), 3):
        raise ValueError(f"windows must have shape (B, N, {len(JOINT_NAMES)}, 3), got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("windows contain NaN or inf")
    cs = [random_condition(x, rng, min_t_r=min_t_r, single_joint=single_joint) for x in w]
    u = rng.random(len(cs))
    has_key = u >= drop_keypose                                             # (B,)
    has_traj = (u < drop_keypose) | (u >= drop_keypose + drop_trajectory)  # never both dropped
    traj = np.stack([c.trajectory for c in cs]) * has_traj[:, None, None, None]
    mask = np.stack([c.mask for c in cs]) & has_traj[:, None, None]
    key = np.stack([c.keypose for c in cs]) * has_key[:, None, None]
    return {"trajectory": torch.tensor(traj, dtype=torch.float32),
            "traj_mask": torch.tensor(mask),
            "keypose": torch.tensor(key, dtype=torch.float32),
            "key_frame": torch.tensor([c.key_frame for c in cs], dtype=torch.int64),
            "keypose_mask": torch.tensor(has_key)}


def velocity_loss(x0_hat, x0, weights=None):
    """MDM's velocity loss (Tevet et al. 2023, Eq. (4), ``L_vel``) written on the normalised
    feature rows: mean squared error of the frame-to-frame differences,
    ``‖(x̂₀[i+1] − x̂₀[i]) − (x₀[i+1] − x₀[i])‖²``. It penalises high-frequency jitter of
    x̂₀ that the per-row reconstruction loss barely sees. x0_hat, x0 : (B, T, D); weights :
    None or (D,) column weights (:func:`column_weights`)."""
    se = ((x0_hat[:, 1:] - x0_hat[:, :-1]) - (x0[:, 1:] - x0[:, :-1])) ** 2
    return (se if weights is None else se * weights).mean()


# ----------------------------------------------------------------------------- checkpoints


def _param_digest(model):
    h = hashlib.sha256()
    for p in model.parameters():
        h.update(p.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


def _rng_state(g, rng):
    return {"torch": torch.get_rng_state(), "gen": g.get_state(),
            "numpy": rng.bit_generator.state}


def _set_rng_state(state, g, rng):
    torch.set_rng_state(state["torch"])
    g.set_state(state["gen"])
    rng.bit_generator.state = state["numpy"]


# ----------------------------------------------------------------------------- training


def _split_kwargs(kwargs):
    t_fields = {f.name for f in dataclasses.fields(TrainConfig)}
    m_fields = {f.name for f in dataclasses.fields(DenoiserConfig)}
    unknown = sorted(set(kwargs) - t_fields - m_fields)
    if unknown:
        raise ValueError(f"unknown options {unknown}; see `python -m physlab.motion.train -h`")
    tk = {k: v for k, v in kwargs.items() if k in t_fields}
    mk = {k: v for k, v in kwargs.items() if k in m_fields and k not in t_fields}
    return tk, mk


def warmup_cosine_lr(cfg, step):
    """Learning rate of optimiser step ``step``: linear warm-up to ``cfg.lr`` over
    ``cfg.warmup`` steps, then cosine decay to ``cfg.min_lr`` at ``cfg.steps`` (any config
    with these four fields; also the evaluator's)."""
    if step < cfg.warmup:
        return cfg.lr * (step + 1) / cfg.warmup
    frac = (step - cfg.warmup) / max(1, cfg.steps - cfg.warmup)
    return cfg.min_lr + 0.5 * (cfg.lr - cfg.min_lr) * (1 + math.cos(math.pi * min(1.0, frac)))


def train(**kwargs):
    """Train (or resume) one stage; keyword names = the CLI flags (``--batch-size`` ->
    ``batch_size``), fields of :class:`TrainConfig` and :class:`DenoiserConfig`.

    Under ``torchrun`` (``WORLD_SIZE > 1``) it joins a gloo process group and wraps the
    network in DistributedDataParallel; each rank draws its own batches (seed + rank) and
    only rank 0 prints and writes checkpoints.

    Returns
    -------
    dict: ``path`` of the checkpoint, ``step``, ``trained`` (optimiser steps this call ran:
    0 when the checkpoint at ``out`` already had ``steps``), ``loss`` (last step's total
    loss; the checkpoint's when nothing was trained), ``windows_per_s`` (training throughput
    over all ranks, excluding the first step; NaN when nothing was trained),
    ``n_params`` / ``n_trainable``, ``param_digests`` (per rank).
    """
    import torch.distributed as dist
    from tqdm.auto import tqdm

    tk, mk = _split_kwargs(kwargs)
    user_mk = dict(mk)
    if tk.get("smoke"):
        tk = {"steps": 3, "batch_size": 8, "max_clips": 3, "text_encoder": "hash",
              "checkpoint_every": 2, "warmup": 1, **tk}
        mk = {**SMOKE_MODEL, **mk}
    if not tk.get("out"):
        stage = tk.get("stage", "base")
        tk["out"] = f"runs/smoke_{stage}.pt" if tk.get("smoke") else f"runs/{stage}.pt"
    cfg = TrainConfig(**tk)

    world = int(os.environ.get("WORLD_SIZE", "1"))
    rank = int(os.environ.get("RANK", "0"))
    ddp = world > 1
    if ddp and not dist.is_initialized():
        dist.init_process_group("gloo")
    threads = cfg.num_threads or max(1, (os.cpu_count() or 1) // world)
    torch.set_num_threads(threads)
    torch.manual_seed(cfg.seed + rank)
    g = torch.Generator().manual_seed(cfg.seed + 1000 * (rank + 1))
    rng = np.random.default_rng(cfg.seed + 7919 * (rank + 1))
    out = Path(cfg.out)

    resume = load_checkpoint(out) if cfg.resume and out.is_file() else None
    if resume is not None and resume["stage"] != cfg.stage:
        raise ValueError(f"{out} holds a '{resume['stage']}' checkpoint but --stage is "
                         f"'{cfg.stage}'; use another --out")
    base_ckpt = None
    if cfg.stage == "align":
        if ddp:
            raise ValueError("stage 'align' runs in one process (its 2D encoders are small); "
                             "start it with python, not torchrun")
        base_ckpt = load_checkpoint(cfg.base_ckpt)
        variant = controlnet_variant(base_ckpt)
        if base_ckpt["stage"] not in ("control", "align") or variant != "adapter":
            kind = "" if variant == "adapter" else controlnet_variant_label(variant) + " "
            raise ValueError(f"--base-ckpt {cfg.base_ckpt} is a {kind}'{base_ckpt['stage']}'"
                             f" checkpoint; stage 'align' needs the ControlNet + adapter "
                             f"model of --stage control")
    if cfg.stage == "control":
        base_ckpt = load_checkpoint(cfg.base_ckpt)
        if base_ckpt["stage"] in ("control", "align"):   # its frozen base: another variant
            base_ckpt = dict(base_ckpt, stage="base", model={
                k[len("base."):]: v for k, v in base_ckpt["model"].items()
                if k.startswith("base.")})
        if base_ckpt["stage"] != "base":
            raise ValueError(f"--base-ckpt {cfg.base_ckpt} is a '{base_ckpt['stage']}' "
                             f"checkpoint; give the output of --stage base (or a control "
                             f"checkpoint, whose frozen base is then used)")
    src = resume or base_ckpt
    if src is not None:        # model config, stats, schedule and texts of the earlier run
        model_cfg = DenoiserConfig.from_dict(src["model_config"])
        stats = FeatureStats(**src["feature_stats"])
        from .text import EmbeddingCache
        cache = EmbeddingCache.from_state_dict(src["text_cache"])
        sched = NoiseScheduler.from_dict(src["scheduler"])
        if user_mk and rank == 0:
            print(f"note: model options {sorted(user_mk)} ignored; the model config comes from "
                  f"{out if resume else cfg.base_ckpt}", file=sys.stderr)
        if cfg.pelvis_scale != 1 and not resume and rank == 0:
            print(f"note: --pelvis-scale {cfg.pelvis_scale:g} ignored; the feature statistics "
                  f"come from {cfg.base_ckpt}", file=sys.stderr)
    else:
        rep = mk.pop("representation", DEFAULT_REPRESENTATION)
        dims = DenoiserConfig.for_representation(rep)
        mk = {"feature_dim": dims.feature_dim, "n_frames": dims.n_frames, **mk}
        mk.setdefault("smooth_basis", DEFAULT_SMOOTH_BASIS if rep == "absolute" else 0)
        model_cfg = DenoiserConfig(representation=rep, **mk)
        if model_cfg.smooth_basis and cfg.prediction != "sample":
            raise ValueError(f"--smooth-basis {model_cfg.smooth_basis} needs --prediction sample "
                             f"(it low-passes x̂₀; a noise prediction must keep every "
                             f"frequency); use --smooth-basis 0")
        if model_cfg.skip and cfg.prediction != "sample":
            raise ValueError(f"--skip needs --prediction sample (it writes x̂₀ as √ᾱ_t x_t + "
                             f"√(1 − ᾱ_t) F), got --prediction {cfg.prediction}; use --no-skip")
        stats, cache = None, None
        sched = NoiseScheduler(SchedulerConfig(**SCHEDULERS[cfg.scheduler],
                                               prediction_type=cfg.prediction))
    if cfg.text_encoder == "hash" and cache is not None:
        cache.encoder = hash_encoder
    data = prepare_data(cfg, stats=stats, cache=cache, representation=model_cfg.representation)
    stats, cache = data["stats"], data["cache"]
    if model_cfg.n_frames != data["x0"].shape[1]:
        raise ValueError(f"model n_frames={model_cfg.n_frames} but windows have "
                         f"{data['x0'].shape[1]} feature rows")
    p_drop = model_cfg.cond_drop_prob if cfg.cond_drop_prob < 0 else cfg.cond_drop_prob
    if cfg.pelvis_loss_weight != 1 and model_cfg.representation != "absolute":
        raise ValueError(f"pelvis_loss_weight {cfg.pelvis_loss_weight} needs the 'absolute' "
                         f"representation, got {model_cfg.representation!r}")
    if cfg.pelvis_loss_weight != 1 and cfg.stage != "base" and rank == 0:
        print(f"note: --pelvis-loss-weight {cfg.pelvis_loss_weight:g} applies to --stage base "
              f"only; ignored", file=sys.stderr)
    col_w = column_weights(model_cfg.feature_dim, cfg.pelvis_loss_weight)

    base = MotionDenoiser(model_cfg).set_schedule(sched.alphas_cumprod)  # config.skip only
    if cfg.stage == "base":
        model = base
    elif cfg.stage == "align":
        model = ControlledDenoiser(base, sketch_encoders=True,
                                   control_head=has_control_head(base_ckpt))
        weights = {k: v.float() for k, v in base_ckpt["model"].items()
                   if not k.startswith("sketch_")}
        missing, unexpected = model.load_state_dict(weights, strict=False)
        if unexpected or any(not k.startswith("sketch_") for k in missing):
            raise ValueError(f"--base-ckpt {cfg.base_ckpt} does not fit a ControlNet + adapter "
                             f"model: missing {missing[:3]}, unexpected {unexpected[:3]}")
        for name, p in model.named_parameters():
            p.requires_grad_(name.startswith("sketch_"))
    else:
        base.load_state_dict(base_ckpt["model"])
        model = ControlledDenoiser(base, single_controlnet=cfg.single_controlnet,
                                   double_controlnet=cfg.double_controlnet,
                                   sketch_encoders=cfg.direct_2d,
                                   control_head=cfg.control_head)
    params = [p for p in model.parameters() if p.requires_grad]
    opt = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
    step = 0
    if resume is not None:
        was_2d = resume.get("train_config", {}).get("direct_2d", False)
        if cfg.stage == "control" and was_2d != cfg.direct_2d:
            raise ValueError(f"{out} was trained with direct_2d={was_2d}; use another --out")
        if cfg.stage == "control" and resume["single_controlnet"] != cfg.single_controlnet:
            raise ValueError(f"{out} was trained with single_controlnet="
                             f"{resume['single_controlnet']}; use another --out")
        if cfg.stage == "control" and (bool(resume.get("double_controlnet", False))
                                       != cfg.double_controlnet):
            raise ValueError(f"{out} was trained with double_controlnet="
                             f"{resume.get('double_controlnet', False)}; use another --out")
        if cfg.stage == "control" and has_control_head(resume) != cfg.control_head:
            raise ValueError(f"{out} was trained with control_head={has_control_head(resume)}; "
                             f"use another --out")
        model.load_state_dict(resume["model"])
        opt.load_state_dict(resume["optimizer"])
        step = int(resume["step"])
        states = resume.get("rng") or []
        if len(states) == world:
            _set_rng_state(states[rank], g, rng)
        elif rank == 0:
            print(f"note: resuming with {world} processes from a run with {len(states)}; "
                  f"random streams restart", file=sys.stderr)
    net = (torch.nn.parallel.DistributedDataParallel(
        model, find_unused_parameters=cfg.direct_2d) if ddp else model)
    model.train()
    if cfg.stage == "align":                 # the generator is frozen: no dropout in it either
        model.eval()
        model.sketch_traj_encoder.train()
        model.sketch_keypose_encoder.train()

    mean = torch.tensor(stats.mean, dtype=torch.float32)
    std = torch.tensor(stats.std, dtype=torch.float32)
    x0_all, text_idx, text_emb = data["x0"], data["text_index"], data["text_emb"]
    plain_idx = data["plain_index"]                      # TrainConfig.style_drop
    joints_np = data["joints"]
    joints_all = torch.tensor(joints_np, dtype=torch.float32)
    N, B = len(x0_all), cfg.batch_size
    weights = data["sample_weights"] if cfg.balance > 0 else None        # None: bit-identical

    def checkpoint(loss):
        digests = [_param_digest(model)]
        rngs = [_rng_state(g, rng)]
        if ddp:
            digests, rngs = [None] * world, [None] * world
            dist.all_gather_object(digests, _param_digest(model))
            dist.all_gather_object(rngs, _rng_state(g, rng))
        if rank == 0:
            save_checkpoint(out, {
                "kind": CHECKPOINT_KIND, "version": CHECKPOINT_VERSION, "stage": cfg.stage,
                "single_controlnet": cfg.single_controlnet,
                "double_controlnet": cfg.double_controlnet,
                "model_config": model_cfg.to_dict(), "train_config": dataclasses.asdict(cfg),
                "model": model.state_dict(), "optimizer": opt.state_dict(), "step": step,
                "rng": rngs, "feature_stats": {"mean": stats.mean, "std": stats.std},
                "scheduler": sched.to_dict(), "text_cache": cache.state_dict(),
                "param_digests": digests, "loss": loss, "world_size": world,
                "train_takes": data["train_takes"]})
        return digests

    def autocast():                      # --precision bf16: forward passes in bfloat16
        return torch.autocast("cpu", dtype=torch.bfloat16, enabled=cfg.precision == "bf16")

    bar = tqdm(total=cfg.steps, initial=step, disable=not (cfg.progress and rank == 0),
               desc=f"train {cfg.stage}")
    loss_v = float(resume.get("loss", float("nan"))) if resume is not None else float("nan")
    digests, t_start, n_timed, first_step = None, None, 0, step
    try:
        while step < cfg.steps:
            for group in opt.param_groups:
                group["lr"] = warmup_cosine_lr(cfg, step)
            idx = (torch.randint(N, (B,), generator=g) if weights is None        # (B,)
                   else torch.multinomial(weights, B, replacement=True, generator=g))
            x0 = x0_all[idx]                                                     # (B, T, D)
            ti = text_idx[idx]
            if cfg.style_drop > 0:                  # only then: other runs keep their stream
                ti = torch.where(torch.rand(B, generator=g) < cfg.style_drop,
                                 plain_idx[idx], ti)
            a = text_emb[ti]                                                     # (B, 384)
            t = sched.sample_timesteps(B, generator=g)                           # (B,)
            noise = torch.randn(x0.shape, generator=g)                           # (B, T, D)
            x_t = sched.add_noise(x0, noise, t)
            drop = torch.rand(B, generator=g) < p_drop                           # (B,) CFG
            target = sched.training_target(x0, noise, t)                         # ε, v or x0
            if cfg.stage == "base":
                with autocast():
                    out_ = net(x_t, t, a, drop).float()
                loss = recon_loss(out_, target, t, sched, cfg.snr_cap, col_w)
                parts = {}
                if cfg.lambda_vel > 0:
                    l_vel = velocity_loss(sched.split_output(out_, x_t, t)[0], x0, col_w)
                    loss = loss + cfg.lambda_vel * l_vel
                    parts = {"vel": l_vel.item()}
            elif cfg.stage == "align":
                cond = condition_batch(joints_np[idx.numpy()], rng, cfg.min_t_r,
                                       single_joint=cfg.single_joint)
                sketch = sketch_batch(cond, rng, noise=cfg.sketch_noise)
                proj = camera_projections(sketch["camera"]) if cfg.lambda_tr_2d else None

                def generation_loss(out, idx=idx, cond=cond, proj=proj):         # Eq. (9)
                    with torch.autocast("cpu", enabled=False):       # losses in float32
                        x0_hat, _ = sched.split_output(out.float(), x_t, t)
                        l_tr, l_key = control_losses(x0_hat, joints_all[idx], cond, mean,
                                                     std, model_cfg.representation)
                        loss = cfg.lambda_tr * l_tr + cfg.lambda_key * l_key
                        if proj is not None:                         # Eq. (16) in training
                            loss = loss + cfg.lambda_tr_2d * projected_trajectory_loss(
                                x0_hat, joints_all[idx], cond["traj_mask"], proj, mean, std,
                                model_cfg.representation)
                    return loss

                with autocast():
                    terms = alignment_losses(model, x_t, t, a, cond, sketch, target, drop,
                                             tau=cfg.tau, recon=cfg.lambda_recon > 0,
                                             generation_loss=generation_loss)
                terms = {k: v.float() for k, v in terms.items()}
                loss = (cfg.lambda_match * terms["match"] + cfg.lambda_recon * terms["recon"]
                        + cfg.lambda_contrast * terms["contrast"])                # Eq. (13)
                parts = {k: v.item() for k, v in terms.items()}
            else:
                cond = condition_batch(joints_np[idx.numpy()], rng, cfg.min_t_r,
                                       cfg.drop_keypose, cfg.drop_trajectory, cfg.single_joint)
                net_cond = ({**cond, **sketch_batch(cond, rng, noise=cfg.sketch_noise)}
                            if cfg.direct_2d else cond)
                with autocast():
                    out_ = net(x_t, t, a, net_cond, drop).float()
                l_rec = recon_loss(out_, target, t, sched, cfg.snr_cap)          # Eq. (5)
                x0_hat, _ = sched.split_output(out_, x_t, t)                     # Eq. (7)
                l_tr, l_key = control_losses(x0_hat, joints_all[idx], cond, mean, std,
                                             model_cfg.representation)
                loss = l_rec + cfg.lambda_tr * l_tr + cfg.lambda_key * l_key     # Eq. (9)
                parts = {"rec": l_rec.item(), "tr": l_tr.item(), "key": l_key.item()}
                if cfg.lambda_vel > 0:
                    l_vel = velocity_loss(x0_hat, x0)
                    loss = loss + cfg.lambda_vel * l_vel
                    parts["vel"] = l_vel.item()
            if not torch.isfinite(loss):
                raise FloatingPointError(f"loss became {loss.item()} at step {step}; lower --lr "
                                         f"or --lambda-tr / --lambda-key")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            if cfg.grad_clip > 0:
                torch.nn.utils.clip_grad_norm_(params, cfg.grad_clip)
            opt.step()
            step += 1
            loss_v = loss.item()
            if t_start is None:
                t_start = time.perf_counter()       # time from the end of the first step
            else:
                n_timed += 1
            bar.update(1)
            bar.set_postfix(loss=f"{loss_v:.4f}", **{k: f"{v:.4f}" for k, v in parts.items()})
            if step % cfg.checkpoint_every == 0 or step == cfg.steps:
                digests = checkpoint(loss_v)
    except KeyboardInterrupt:
        bar.close()
        if not ddp and step > 0:          # keep the work done; rerun the command to resume
            checkpoint(loss_v)
            print(f"interrupted: checkpoint of step {step} written to {out}", file=sys.stderr)
        raise
    bar.close()
    if digests is None:                # nothing left to train: report the loaded state
        digests = [resume.get("param_digests", [None])[0]] if resume else None
    elapsed = time.perf_counter() - t_start if t_start is not None else 0.0
    wps = n_timed * B * world / elapsed if n_timed and elapsed > 0 else float("nan")
    if ddp:
        dist.barrier()
    return {"path": out, "step": step, "trained": step - first_step, "loss": loss_v,
            "windows_per_s": wps,
            "n_params": count_parameters(model),
            "n_trainable": count_parameters(model, trainable_only=True),
            "param_digests": digests, "rank": rank, "world_size": world}


# ----------------------------------------------------------------------------- CLI


def _parser():
    from physlab._cli import Parser

    p = Parser(prog="python -m physlab.motion.train", description=__doc__.split("\n\n")[0],
               epilog="examples:\n"
                      "  %(prog)s --stage base --steps 4000 --out runs/base.pt\n"
                      "  %(prog)s --stage control --base-ckpt runs/base.pt --steps 4000 "
                      "--out runs/control.pt\n"
                      "  %(prog)s --stage base --smoke --out /tmp/smoke.pt    # seconds")
    for cls in (TrainConfig, DenoiserConfig):
        group = p.add_argument_group(cls.__name__)
        for f in dataclasses.fields(cls):
            if cls is DenoiserConfig and f.name in {x.name for x in dataclasses.fields(TrainConfig)}:
                continue
            flag = "--" + f.name.replace("_", "-")
            if f.type in ("bool", bool):
                group.add_argument(flag, action=argparse.BooleanOptionalAction, default=None)
            else:
                typ = {"int": int, "float": float, "str": str}.get(f.type, f.type)
                group.add_argument(flag, type=typ, default=None,
                                   help=f"default {f.default!r}")
    p.add_argument("--export", default="", help="after training, write an fp16 inference "
                                                "copy of the checkpoint to this path")
    return p


def main(argv=None):
    from physlab._cli import stop_like_ctrl_c

    args = vars(_parser().parse_args(argv))
    args.pop("debug", None)
    export = args.pop("export")
    stop_like_ctrl_c()                  # `kill PID` / Ctrl-C: checkpoint, then resume later
    kwargs = {k: v for k, v in args.items() if v is not None}
    res = train(**kwargs)
    if res["rank"] == 0:
        speed = (f"{res['windows_per_s']:.1f} windows/s" if res["trained"] else
                 NOTHING_LEFT_TO_TRAIN)
        print(f"stage {kwargs.get('stage', 'base')}: step {res['step']}, loss "
              f"{res['loss']:.4f}, {speed}, "
              f"{res['n_trainable']:,} trainable of {res['n_params']:,} parameters -> "
              f"{res['path']}")
        if export:
            export_weights(res["path"], export)
            print(f"inference weights (fp16) -> {export}")
    if int(os.environ.get("WORLD_SIZE", "1")) > 1:
        import torch.distributed as dist
        # every rank waits for rank 0's printing / export, then all leave the group together:
        # a rank tearing gloo down while its peer still talks to it can abort at exit
        dist.barrier()
        dist.destroy_process_group()
    return res


if __name__ == "__main__":
    from physlab._cli import guard

    sys.exit(guard("python -m physlab.motion.train", main))
