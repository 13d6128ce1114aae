"""The noise scheduler of a motion diffusion model: forward noising, DDPM and DDIM sampling,
classifier-free guidance (Sketch2Anim Sec. 4 and 6).

The scheduler knows nothing about the network, in the manner of diffusers' ``DDPMScheduler`` /
``DDIMScheduler``: a network ``eps_theta(x_t, t, cond)`` is trained with :meth:`~NoiseScheduler.
add_noise` and :meth:`~NoiseScheduler.training_target`, and sampled with the loop written out
in :meth:`~NoiseScheduler.sample` (one :meth:`~NoiseScheduler.ddim_step` or
:meth:`~NoiseScheduler.ddpm_step` per timestep).

References
----------
* **DDPM** — Ho, Jain & Abbeel 2020, *Denoising Diffusion Probabilistic Models*: forward
  process Eq. (4), posterior Eqs. (6)–(7), ε-loss Eq. (14), sampling Algorithm 2.
* **DDIM** — Song, Meng & Ermon 2021, *Denoising Diffusion Implicit Models*: x̂₀ Eq. (9),
  the generalised step Eq. (12), its noise level σ_t(η) Eq. (16).
* **Cosine schedule** — Nichol & Dhariwal 2021, *Improved DDPM*, Eq. (17).
* **v-prediction** — Salimans & Ho 2022, *Progressive Distillation*, Sec. 4 / App. D.
* **Classifier-free guidance** — Ho & Salimans 2022; written as in **Sketch2Anim** Eq. (14).
* **Sketch2Anim** (Zhong et al. 2025): ε-prediction, loss Eq. (5), x̂₀ Eq. (7), guidance
  Eq. (14) with ``w_c = 7.5``, DDIM sampling (supp. Algorithm 1, line 12).

Conventions
-----------
* Timesteps are **0-based integers** ``t = 0 .. T-1`` (``T = num_train_timesteps``) as in
  diffusers: code ``t`` is the paper's ``t + 1``, so ``t = 0`` is the least noisy level and
  ``t = T-1`` is (almost) pure noise. ``t_prev = -1`` means "the clean sample x₀", whose
  ``ᾱ`` is 1.
* ``alphas_cumprod[t]`` is ᾱ_t = ∏_{s≤t} (1 − β_s). Sketch2Anim Eq. (7) writes this
  cumulative product as ``α_t``.
* Arrays are torch tensors of any shape ``(B, ...)`` (e.g. a motion ``(B, N, D)`` or a
  latent ``(B, L, C)``); ``t`` is an ``int`` / 0-d integer tensor (the same level for the
  whole batch) or a ``(B,)`` integer tensor (one level per sample). The schedule is kept in
  float64 on the CPU and cast to the dtype and device of the data at each use.

A training step (Sketch2Anim Eq. (5), DDPM Eq. (14))::

    t = sched.sample_timesteps(B, generator=g)            # (B,) int64
    noise = torch.randn(x0.shape, generator=g)            # (B, N, D)
    x_t = sched.add_noise(x0, noise, t)                   # (B, N, D)
    loss = ((model(x_t, t, cond) - sched.training_target(x0, noise, t)) ** 2).mean()

Sampling with guidance (Sketch2Anim Sec. 6: DDIM, ``w_c = 7.5``)::

    x0 = sched.sample(lambda x, t, c: model(x, t, c), (B, N, D), steps=50, method="ddim",
                      guidance_scale=7.5, cond=cond, uncond=null_cond, generator=g)

Sketch2Anim does not state its scheduler constants. MLD (Chen et al. 2023,
``configs/modules/scheduler.yaml``), the latent motion diffusion model of that family, uses
``SchedulerConfig(beta_start=0.00085, beta_end=0.012, beta_schedule="scaled_linear",
set_alpha_to_one=False, steps_offset=1)`` with 50 DDIM steps and ``eta = 0``.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import torch
from tqdm.auto import tqdm

__all__ = [
    "BETA_SCHEDULES", "PREDICTION_TYPES", "VARIANCE_TYPES", "TIMESTEP_SPACINGS",
    "DEFAULT_GUIDANCE_SCALE", "SchedulerConfig", "StepOutput", "NoiseScheduler",
    "make_betas", "classifier_free_guidance",
]

BETA_SCHEDULES = ("linear", "scaled_linear", "cosine")
PREDICTION_TYPES = ("epsilon", "sample", "v_prediction")
VARIANCE_TYPES = ("fixed_small", "fixed_large")
TIMESTEP_SPACINGS = ("leading", "trailing", "linspace")
#: Sketch2Anim Sec. 7.1: "The weight of classifier-free guidance, w_c, is set to 7.5".
DEFAULT_GUIDANCE_SCALE = 7.5
#: Offset ``s`` of the cosine schedule (Nichol & Dhariwal 2021, Sec. 3.2).
COSINE_S = 0.008
#: Upper bound of β in the cosine schedule, to avoid a singularity at t = T (ibid.).
COSINE_MAX_BETA = 0.999


@dataclass(frozen=True)
class SchedulerConfig:
    """Everything needed to rebuild a :class:`NoiseScheduler`; store :meth:`NoiseScheduler.
    to_dict` in a checkpoint next to the network's weights."""

    num_train_timesteps: int = 1000     # T: diffusion steps the network is trained on
    beta_start: float = 1e-4            # β of the first step (DDPM Sec. 4: 1e-4)
    beta_end: float = 0.02              # β of the last step (DDPM Sec. 4: 0.02)
    beta_schedule: str = "linear"       # "linear" | "scaled_linear" | "cosine" (ignores beta_*)
    prediction_type: str = "epsilon"    # network output: "epsilon" (Sketch2Anim) | "sample"
                                        # | "v_prediction"
    variance_type: str = "fixed_small"  # DDPM reverse variance: β̃_t "fixed_small" | β_t
                                        # "fixed_large"
    clip_sample: bool = False           # clip x̂₀ to ±clip_sample_range in the steps (for images
    clip_sample_range: float = 1.0      # in [-1, 1]); off for z-scored motion features
    timestep_spacing: str = "leading"   # inference timesteps: "leading" | "trailing" | "linspace"
    steps_offset: int = 0               # added to "leading" timesteps (Stable Diffusion / MLD: 1)
    set_alpha_to_one: bool = True       # DDIM's ᾱ after the last step: 1 (True) or ᾱ_0 (False)

    def __post_init__(self):
        T = self.num_train_timesteps
        if isinstance(T, bool) or not isinstance(T, (int, np.integer)) or T < 1:
            raise ValueError(f"num_train_timesteps must be an integer >= 1, got {T!r}")
        if not 0.0 < self.beta_start <= self.beta_end < 1.0:
            raise ValueError("need 0 < beta_start <= beta_end < 1, got beta_start="
                             f"{self.beta_start}, beta_end={self.beta_end}")
        for name, allowed in (("beta_schedule", BETA_SCHEDULES),
                              ("prediction_type", PREDICTION_TYPES),
                              ("variance_type", VARIANCE_TYPES),
                              ("timestep_spacing", TIMESTEP_SPACINGS)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name} must be one of {allowed}, got {getattr(self, name)!r}")
        if not self.clip_sample_range > 0:
            raise ValueError(f"clip_sample_range must be > 0, got {self.clip_sample_range}")
        k = self.steps_offset
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0:
            raise ValueError(f"steps_offset must be an integer >= 0, got {self.steps_offset!r}")


class StepOutput(NamedTuple):
    """Result of one reverse step: ``x_prev`` (the sample at ``t_prev``) and ``x0`` (x̂₀,
    the clean sample predicted at ``t``, after clipping if enabled); both shaped like x_t."""

    x_prev: torch.Tensor
    x0: torch.Tensor


def make_betas(num_train_timesteps=1000, beta_start=1e-4, beta_end=0.02, beta_schedule="linear"):
    """The variance schedule β_t, ``t = 0 .. T-1``: ``(T,)`` float64 tensor.

    * ``"linear"`` — β evenly spaced from ``beta_start`` to ``beta_end`` (DDPM Sec. 4);
    * ``"scaled_linear"`` — √β evenly spaced (Stable Diffusion, MLD);
    * ``"cosine"`` — ᾱ(τ) = f(τ) / f(0), f(τ) = cos²((τ/T + s)/(1 + s) · π/2), s = 0.008
      (Nichol & Dhariwal 2021 Eq. (17)); β_t = 1 − ᾱ(t+1)/ᾱ(t), capped at 0.999.
      ``beta_start`` / ``beta_end`` are ignored (diffusers calls it ``"squaredcos_cap_v2"``).
    """
    T = num_train_timesteps
    if beta_schedule == "linear":
        return torch.linspace(beta_start, beta_end, T, dtype=torch.float64)
    if beta_schedule == "scaled_linear":
        return torch.linspace(beta_start ** 0.5, beta_end ** 0.5, T, dtype=torch.float64) ** 2
    if beta_schedule == "cosine":
        tau = torch.arange(T + 1, dtype=torch.float64) / T
        f = torch.cos((tau + COSINE_S) / (1 + COSINE_S) * math.pi / 2) ** 2
        alpha_bar = f / f[0]                                                    # Eq. (17)
        return (1 - alpha_bar[1:] / alpha_bar[:-1]).clamp(max=COSINE_MAX_BETA)
    raise ValueError(f"beta_schedule must be one of {BETA_SCHEDULES}, got {beta_schedule!r}")


def classifier_free_guidance(eps_uncond, eps_cond, w=DEFAULT_GUIDANCE_SCALE):
    """Classifier-free guidance, Sketch2Anim Eq. (14): ``ε = ε_u + w (ε_c − ε_u)``.

    ``w = 0`` returns the unconditional prediction, ``w = 1`` the conditional one (both
    exactly), ``w > 1`` extrapolates away from the unconditional one. This is the convention
    of Sketch2Anim (``w_c = 7.5``), GLIDE and diffusers (``guidance_scale``). Ho & Salimans
    2022 write ``(1 + w') ε_c − w' ε_u``, i.e. ``w = 1 + w'``: their ``w' = 0`` is our
    ``w = 1``. In Sketch2Anim ε_u is not a fully unconditional prediction: it keeps the
    action word, ``ε_θ(z_t, t, a)``, while ε_c adds the keypose and trajectory.

    eps_uncond, eps_cond : tensors of the same shape ``(B, ...)``
    w : float, or a tensor broadcastable to them (e.g. ``(B, 1, 1)`` for one scale per sample)
    Returns a tensor shaped like ``eps_cond``.
    """
    if eps_uncond.shape != eps_cond.shape:
        raise ValueError(f"eps_uncond and eps_cond must have the same shape, got "
                         f"{tuple(eps_uncond.shape)} and {tuple(eps_cond.shape)}")
    if not bool(torch.isfinite(torch.as_tensor(w)).all()):
        raise ValueError(f"guidance scale w must be finite, got {w}")
    if isinstance(w, torch.Tensor):
        w = w.to(device=eps_cond.device, dtype=eps_cond.dtype)
    # torch.lerp(a, b, w) = a + w (b − a), computed so that w = 0 and w = 1 are exact.
    return torch.lerp(eps_uncond, eps_cond, w)                                  # Eq. (14)


def _check_finite(x, name):
    if not isinstance(x, torch.Tensor):
        raise ValueError(f"{name} must be a torch tensor, got {type(x).__name__}")
    if not torch.isfinite(x).all():
        raise ValueError(f"{name} contains NaN or inf")


def _check_same_shape(a, b, name_a, name_b):
    if a.shape != b.shape:
        raise ValueError(f"{name_a} and {name_b} must have the same shape, got "
                         f"{tuple(a.shape)} and {tuple(b.shape)}")


class NoiseScheduler:
    """Variance schedule and DDPM / DDIM update rules (diffusers-style, no network inside).

    ``NoiseScheduler()`` uses the defaults of :class:`SchedulerConfig`;
    ``NoiseScheduler(config)`` or ``NoiseScheduler(beta_schedule="cosine", ...)`` set them.

    Attributes
    ----------
    config : SchedulerConfig
    betas : (T,) float64 tensor, β_t
    alphas : (T,) float64 tensor, α_t = 1 − β_t
    alphas_cumprod : (T,) float64 tensor, ᾱ_t = ∏_{s≤t} α_s, strictly decreasing in (0, 1)
    timesteps : (S,) int64 tensor, descending; set by :meth:`set_timesteps` (initially all T)
    """

    def __init__(self, config: SchedulerConfig | None = None, **kwargs):
        if config is not None and kwargs:
            raise ValueError("pass either a SchedulerConfig or keyword arguments, not both "
                             f"(got config and {sorted(kwargs)})")
        if config is None:
            config = SchedulerConfig(**kwargs)
        if not isinstance(config, SchedulerConfig):
            raise ValueError(f"config must be a SchedulerConfig, got {type(config).__name__}")
        self.config = config
        c = config
        self.num_train_timesteps = int(c.num_train_timesteps)
        self.betas = make_betas(self.num_train_timesteps, c.beta_start, c.beta_end,
                                c.beta_schedule)
        self.alphas = 1.0 - self.betas
        self.alphas_cumprod = torch.cumprod(self.alphas, dim=0)
        self.num_inference_steps = self.num_train_timesteps
        self.timesteps = torch.arange(self.num_train_timesteps - 1, -1, -1, dtype=torch.int64)

    def __repr__(self):
        return f"NoiseScheduler({self.config})"

    # ------------------------------------------------------------------ config round trip

    def to_dict(self) -> dict:
        """The config as a plain JSON-serialisable dict (for checkpoints)."""
        return {k: (v.item() if isinstance(v, np.generic) else v)
                for k, v in dataclasses.asdict(self.config).items()}

    @classmethod
    def from_dict(cls, d: dict) -> NoiseScheduler:
        """Rebuild from :meth:`to_dict`; missing keys take their defaults."""
        known = {f.name for f in dataclasses.fields(SchedulerConfig)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown scheduler config keys {unknown}; expected a subset of "
                             f"{sorted(known)}")
        return cls(SchedulerConfig(**d))

    # ------------------------------------------------------------------ helpers

    def _timesteps(self, t, name="t", allow_final=False):
        """Validate ``t`` and return it as an int64 CPU tensor of shape () or (B,)."""
        T = self.num_train_timesteps
        if isinstance(t, (bool, np.bool_)):
            raise ValueError(f"{name} must be an integer timestep, got {t!r}")
        if isinstance(t, (int, np.integer)):
            t = torch.tensor(int(t), dtype=torch.int64)
        elif isinstance(t, (torch.Tensor, np.ndarray)):
            t = torch.as_tensor(t)
            if t.dtype == torch.bool or t.is_floating_point() or t.is_complex():
                raise ValueError(f"{name} must hold integer timesteps, got dtype {t.dtype}; "
                                 "round and convert with .long()")
            t = t.detach().to("cpu", torch.int64)
        else:
            raise ValueError(f"{name} must be an int or an integer tensor, got "
                             f"{type(t).__name__} {t!r}")
        if t.ndim > 1:
            raise ValueError(f"{name} must be a scalar or a (B,) tensor, got shape "
                             f"{tuple(t.shape)}")
        lo = -1 if allow_final else 0
        if t.numel() and (int(t.min()) < lo or int(t.max()) > T - 1):
            raise ValueError(f"{name} must lie in [{lo}, {T - 1}] (num_train_timesteps={T}), got "
                             f"values in [{int(t.min())}, {int(t.max())}]")
        return t

    @staticmethod
    def _per_sample(v, x):
        """A schedule value at t (shape () or (B,)) as a tensor broadcastable to x (B, ...)."""
        v = torch.as_tensor(v, dtype=torch.float64)
        if v.ndim == 1:
            if x.ndim == 0 or v.shape[0] != x.shape[0]:
                raise ValueError(f"timesteps of shape {tuple(v.shape)} do not match a batch of "
                                 f"shape {tuple(x.shape)}: need one timestep per sample")
            v = v.reshape(-1, *([1] * (x.ndim - 1)))
        return v.to(device=x.device, dtype=x.dtype)

    def _alpha_bar_prev(self, t_prev, final):
        """ᾱ at ``t_prev`` (int64 tensor), with ᾱ = ``final`` where ``t_prev = -1``."""
        a = self.alphas_cumprod[t_prev.clamp(min=0)]
        return torch.where(t_prev >= 0, a, torch.as_tensor(final, dtype=torch.float64))

    def _clip(self, x0):
        if self.config.clip_sample:
            r = self.config.clip_sample_range
            return x0.clamp(-r, r)
        return x0

    # ------------------------------------------------------------------ forward process

    def sample_timesteps(self, batch: int, generator: torch.Generator | None = None,
                         device=None) -> torch.Tensor:
        """Uniform training timesteps ``t ~ U{0, .., T-1}`` (DDPM Algorithm 1): ``(batch,)``
        int64 tensor."""
        if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1:
            raise ValueError(f"batch must be an integer >= 1, got {batch!r}")
        return torch.randint(0, self.num_train_timesteps, (int(batch),), generator=generator,
                             device=device)

    def add_noise(self, x0: torch.Tensor, noise: torch.Tensor, t) -> torch.Tensor:
        """Forward process q(x_t | x_0), DDPM Eq. (4): ``x_t = √ᾱ_t x₀ + √(1 − ᾱ_t) ε``.

        x0, noise : (B, ...) tensors, ``noise ~ N(0, I)``
        t : int or (B,) int tensor in [0, T-1]
        Returns x_t, (B, ...).
        """
        _check_finite(x0, "x0")
        _check_finite(noise, "noise")
        _check_same_shape(x0, noise, "x0", "noise")
        t = self._timesteps(t)
        a = self._per_sample(self.alphas_cumprod[t], x0)
        return a.sqrt() * x0 + (1 - a).sqrt() * noise                            # Eq. (4)

    def training_target(self, x0: torch.Tensor, noise: torch.Tensor, t) -> torch.Tensor:
        """What the network regresses for ``config.prediction_type`` (same shape as x0):

        * ``"epsilon"`` — the noise ε (DDPM Eq. (14), Sketch2Anim Eq. (5));
        * ``"sample"`` — x₀;
        * ``"v_prediction"`` — v = √ᾱ_t ε − √(1 − ᾱ_t) x₀ (Salimans & Ho 2022).
        """
        _check_same_shape(x0, noise, "x0", "noise")
        t = self._timesteps(t)
        kind = self.config.prediction_type
        if kind == "epsilon":
            return noise
        if kind == "sample":
            return x0
        a = self._per_sample(self.alphas_cumprod[t], x0)
        return a.sqrt() * noise - (1 - a).sqrt() * x0

    def predict_x0(self, x_t: torch.Tensor, eps: torch.Tensor, t) -> torch.Tensor:
        """Clean sample from a noise prediction, Sketch2Anim Eq. (7) (DDIM Eq. (9)):
        ``x̂₀ = (x_t − √(1 − ᾱ_t) ε) / √ᾱ_t``. No clipping.

        x_t, eps : (B, ...) tensors; t : int or (B,) int tensor. Returns (B, ...).
        """
        _check_finite(x_t, "x_t")
        _check_finite(eps, "eps")
        _check_same_shape(x_t, eps, "x_t", "eps")
        t = self._timesteps(t)
        a = self._per_sample(self.alphas_cumprod[t], x_t)
        return (x_t - (1 - a).sqrt() * eps) / a.sqrt()                           # Eq. (7)

    def predict_eps(self, x_t: torch.Tensor, x0: torch.Tensor, t) -> torch.Tensor:
        """Noise implied by a clean-sample prediction (Eq. (4) solved for ε):
        ``ε̂ = (x_t − √ᾱ_t x₀) / √(1 − ᾱ_t)``. Shapes as in :meth:`predict_x0`."""
        _check_same_shape(x_t, x0, "x_t", "x0")
        t = self._timesteps(t)
        a = self._per_sample(self.alphas_cumprod[t], x_t)
        return (x_t - a.sqrt() * x0) / (1 - a).sqrt()

    def split_output(self, model_output: torch.Tensor, x_t: torch.Tensor, t):
        """``(x̂₀, ε̂)`` implied by a network output for ``config.prediction_type`` (for
        ``"epsilon"`` x̂₀ is Sketch2Anim Eq. (7)); x̂₀ unclipped. Shapes (B, ...); t int or
        (B,) int tensor."""
        return self._x0_eps(model_output, self._timesteps(t), x_t)

    def _x0_eps(self, model_output, t, x_t):
        """(x̂₀, ε̂) from the network output for ``config.prediction_type``; x̂₀ unclipped."""
        _check_finite(x_t, "x_t")
        _check_finite(model_output, "model_output")
        _check_same_shape(model_output, x_t, "model_output", "x_t")
        a = self._per_sample(self.alphas_cumprod[t], x_t)
        kind = self.config.prediction_type
        if kind == "epsilon":
            eps = model_output
            x0 = (x_t - (1 - a).sqrt() * eps) / a.sqrt()                         # Eq. (7)
        elif kind == "sample":
            x0 = model_output
            eps = (x_t - a.sqrt() * x0) / (1 - a).sqrt()
        else:  # v_prediction, Salimans & Ho 2022 App. D
            x0 = a.sqrt() * x_t - (1 - a).sqrt() * model_output
            eps = (1 - a).sqrt() * x_t + a.sqrt() * model_output
        return x0, eps

    # ------------------------------------------------------------------ DDPM

    def posterior(self, x0: torch.Tensor, x_t: torch.Tensor, t, t_prev=None):
        """Mean and variance of q(x_{t_prev} | x_t, x₀), DDPM Eqs. (6)–(7).

        With ``t_prev = t − 1`` (default) this is
        ``μ̃ = √ᾱ_{t−1} β_t / (1 − ᾱ_t) x₀ + √α_t (1 − ᾱ_{t−1}) / (1 − ᾱ_t) x_t`` and
        ``β̃_t = (1 − ᾱ_{t−1}) / (1 − ᾱ_t) β_t``. For a skipped step (``t_prev < t − 1``) β_t
        and α_t are replaced by the effective ``β' = 1 − ᾱ_t / ᾱ_{t_prev}``, ``α' = 1 − β'``
        (as diffusers' ``DDPMScheduler`` does with fewer inference steps). ``t_prev = -1``
        targets x₀ itself (ᾱ = 1): mean x₀, variance 0.

        x0, x_t : (B, ...) tensors; t, t_prev : int or (B,) int tensors, ``-1 <= t_prev < t``.
        Returns ``(mean, variance)``: mean (B, ...), variance broadcastable to it (the β̃
        of ``variance_type="fixed_small"``).
        """
        _check_same_shape(x0, x_t, "x0", "x_t")
        t = self._timesteps(t)
        t_prev = t - 1 if t_prev is None else self._timesteps(t_prev, "t_prev", allow_final=True)
        if bool((t_prev >= t).any()):
            raise ValueError(f"t_prev must be smaller than t, got t={t.tolist()}, "
                             f"t_prev={t_prev.tolist()}")
        a_t = self.alphas_cumprod[t]
        a_prev = self._alpha_bar_prev(t_prev, 1.0)
        alpha = a_t / a_prev                          # α_t (or α' over a skipped stretch)
        beta = 1 - alpha                              # β_t (or β')
        c0 = a_prev.sqrt() * beta / (1 - a_t)                                    # Eq. (7)
        ct = alpha.sqrt() * (1 - a_prev) / (1 - a_t)                             # Eq. (7)
        var = (1 - a_prev) / (1 - a_t) * beta                                    # Eq. (7)
        mean = self._per_sample(c0, x0) * x0 + self._per_sample(ct, x_t) * x_t
        return mean, self._per_sample(var, x_t)

    def ddpm_step(self, model_output: torch.Tensor, t, x_t: torch.Tensor,
                  generator: torch.Generator | None = None, t_prev=None,
                  noise: torch.Tensor | None = None) -> StepOutput:
        """One ancestral sampling step x_t → x_{t_prev} (DDPM Algorithm 2).

        x̂₀ comes from the network output (Eq. (7) of Sketch2Anim for ε-prediction), is
        clipped if ``config.clip_sample``, and ``x_{t_prev} ~ N(μ̃(x_t, x̂₀), σ²)`` with μ̃
        from DDPM Eq. (7) and σ² = β̃_t (``"fixed_small"``) or β_t (``"fixed_large"``, both
        DDPM Sec. 3.2). No noise is added on the last step (``t_prev = -1``).

        model_output : (B, ...) network output at (x_t, t)
        t : int or (B,) int tensor; t_prev : default ``t − 1`` (``-1`` = final step)
        x_t : (B, ...) current sample
        generator : torch.Generator for the noise; noise : optional explicit z ~ N(0, I)
        Returns :class:`StepOutput` ``(x_prev, x0)``.
        """
        t = self._timesteps(t)
        t_prev = t - 1 if t_prev is None else self._timesteps(t_prev, "t_prev", allow_final=True)
        x0, _ = self._x0_eps(model_output, t, x_t)
        x0 = self._clip(x0)
        mean, var = self.posterior(x0, x_t, t, t_prev)                           # Eqs. (6)-(7)
        if self.config.variance_type == "fixed_large":
            beta = 1 - self.alphas_cumprod[t] / self._alpha_bar_prev(t_prev, 1.0)
            var = self._per_sample(beta, x_t)
        var = var * self._per_sample((t_prev >= 0).double(), x_t)  # no noise into x₀
        z = self._noise_like(x_t, generator, noise)
        return StepOutput(mean + var.sqrt() * z, x0)

    @staticmethod
    def _noise_like(x, generator, noise):
        if noise is None:
            return torch.randn(x.shape, generator=generator, device=x.device, dtype=x.dtype)
        _check_finite(noise, "noise")
        _check_same_shape(noise, x, "noise", "x_t")
        return noise

    # ------------------------------------------------------------------ DDIM

    def set_timesteps(self, num_inference_steps: int, spacing: str | None = None,
                      device=None) -> torch.Tensor:
        """Choose ``S = num_inference_steps`` of the T training timesteps for sampling;
        store and return them as a descending ``(S,)`` int64 tensor (``self.timesteps``).

        ``spacing`` (default ``config.timestep_spacing``), for T = 1000, S = 50:

        * ``"leading"`` — ``k · (T // S) + steps_offset``, k = S−1 .. 0: 980, 960, .., 20, 0
          (DDIM paper and diffusers' default; never visits t = T−1, so the first step starts
          from slightly less than pure noise);
        * ``"trailing"`` — ``round(T − k · T/S) − 1``, k = 0 .. S−1: 999, 979, .., 39, 19
          (starts at the noisiest level; recommended by Lin et al. 2024, "Common diffusion
          noise schedules and sample steps are flawed", Table 2);
        * ``"linspace"`` — ``round(linspace(0, T−1, S))`` reversed: 999, 979, .., 20, 0.

        Each step goes from ``timesteps[i]`` to ``timesteps[i + 1]``, the last one to ``-1``
        (x₀). ``S = T`` with ``"leading"`` and no offset is every timestep (plain DDPM).
        With very few steps "leading" starts far from pure noise (``S = 1`` gives ``[0]``);
        use "trailing" there.
        """
        T = self.num_train_timesteps
        S = num_inference_steps
        if isinstance(S, bool) or not isinstance(S, (int, np.integer)) or S < 1:
            raise ValueError(f"num_inference_steps must be an integer >= 1, got {S!r}")
        if S > T:
            raise ValueError(f"num_inference_steps={S} exceeds num_train_timesteps={T}; "
                             f"use at most {T} steps")
        spacing = self.config.timestep_spacing if spacing is None else spacing
        if spacing == "leading":
            ts = np.arange(S)[::-1] * (T // S) + self.config.steps_offset
        elif spacing == "trailing":
            ts = np.round(np.arange(T, 0, -T / S)).astype(np.int64) - 1
        elif spacing == "linspace":
            ts = np.linspace(0, T - 1, S).round()[::-1]
        else:
            raise ValueError(f"spacing must be one of {TIMESTEP_SPACINGS}, got {spacing!r}")
        ts = torch.as_tensor(ts.copy(), dtype=torch.int64)
        if int(ts.max()) > T - 1:
            raise ValueError(f"steps_offset={self.config.steps_offset} pushes the first "
                             f"'leading' timestep to {int(ts.max())} > {T - 1}; use fewer "
                             "steps or a smaller offset")
        self.num_inference_steps = int(S)
        self.timesteps = ts.to(device) if device is not None else ts
        return self.timesteps

    def ddim_sigma(self, t, t_prev) -> torch.Tensor:
        """σ_t(η = 1) of DDIM Eq. (16), ``√((1 − ᾱ_prev)/(1 − ᾱ_t)) · √(1 − ᾱ_t/ᾱ_prev)``:
        float64 tensor of the shape of ``t``; multiply by η. For consecutive steps σ² = β̃_t."""
        t = self._timesteps(t)
        t_prev = self._timesteps(t_prev, "t_prev", allow_final=True)
        a_t = self.alphas_cumprod[t]
        a_prev = self._alpha_bar_prev(t_prev, self._final_alpha_cumprod())
        return ((1 - a_prev) / (1 - a_t) * (1 - a_t / a_prev)).clamp(min=0).sqrt()  # Eq. (16)

    def _final_alpha_cumprod(self):
        return 1.0 if self.config.set_alpha_to_one else float(self.alphas_cumprod[0])

    def ddim_step(self, model_output: torch.Tensor, t, t_prev, x_t: torch.Tensor,
                  eta: float = 0.0, generator: torch.Generator | None = None,
                  noise: torch.Tensor | None = None) -> StepOutput:
        """One DDIM step x_t → x_{t_prev}, Song et al. 2021 Eq. (12)::

            x_prev = √ᾱ_prev x̂₀ + √(1 − ᾱ_prev − σ²) ε̂ + σ z,   σ = η σ_t   (Eq. (16))

        with x̂₀ from Eq. (9) (= Sketch2Anim Eq. (7)). η = 0 is deterministic (DDIM proper);
        η = 1 on consecutive timesteps is DDPM with β̃_t. For ``t_prev = -1`` ᾱ_prev is 1
        (``set_alpha_to_one``) or ᾱ_0. With ``clip_sample`` x̂₀ is clipped and ε̂ is left as
        predicted (diffusers' default, ``use_clipped_model_output=False``).

        model_output : (B, ...); t : int or (B,) int tensor; t_prev : same, ``-1 <= t_prev < t``
        x_t : (B, ...); eta : η >= 0; generator / noise : for the σ z term (η > 0 only)
        Returns :class:`StepOutput` ``(x_prev, x0)``.
        """
        t = self._timesteps(t)
        t_prev = self._timesteps(t_prev, "t_prev", allow_final=True)
        if bool((t_prev >= t).any()):
            raise ValueError(f"t_prev must be smaller than t, got t={t.tolist()}, "
                             f"t_prev={t_prev.tolist()}")
        if not (math.isfinite(eta) and eta >= 0):
            raise ValueError(f"eta must be a finite number >= 0, got {eta}")
        x0, eps = self._x0_eps(model_output, t, x_t)                             # Eq. (9)
        x0 = self._clip(x0)
        a_prev = self._per_sample(self._alpha_bar_prev(t_prev, self._final_alpha_cumprod()),
                                  x_t)
        sigma = eta * self._per_sample(self.ddim_sigma(t, t_prev), x_t)     # Eq. (16)
        direction = (1 - a_prev - sigma ** 2).clamp(min=0).sqrt() * eps  # "pointing to x_t"
        x_prev = a_prev.sqrt() * x0 + direction                                  # Eq. (12)
        if eta > 0:
            x_prev = x_prev + sigma * self._noise_like(x_t, generator, noise)    # Eq. (12)
        return StepOutput(x_prev, x0)

    def ddim_invert_step(self, model_output: torch.Tensor, t, t_prev,
                         x_prev: torch.Tensor) -> StepOutput:
        """One deterministic DDIM *inversion* step x_{t_prev} → x_t, the mirror of
        :meth:`ddim_step` (Song et al. 2021 Sec. 4.3, ODE form; Sketch2Anim supp. Eq. (17))::

            x_t = √ᾱ_t x̂₀ + √(1 − ᾱ_t) ε̂

        where (x̂₀, ε̂) are read from ``model_output`` = the network at ``(x_{t_prev}, t)``
        (the usual approximation x_t ≈ x_{t_prev} inside the network) and converted at the
        level ``t_prev`` that ``x_prev`` lives on: ε-prediction ``x̂₀ = (x_prev −
        √(1−ᾱ_prev) ε̂)/√ᾱ_prev`` (which makes this exactly Eq. (17),
        ``x_t = √(ᾱ_t/ᾱ_prev) x_prev + (√(1−ᾱ_t) − √(ᾱ_t/ᾱ_prev)√(1−ᾱ_prev)) ε̂``);
        x̂₀-prediction ``ε̂ = (x_prev − √ᾱ_prev x̂₀)/√(1−ᾱ_prev)``; v-prediction
        (Salimans & Ho App. D) at ``t_prev``. From the clean level (``t_prev = -1`` with
        ``set_alpha_to_one``, where 1 − ᾱ_prev = 0) an x̂₀ / v model's ε̂ is read at level t.

        model_output : (B, ...); t : int or (B,) int tensor; t_prev : same, ``-1 <= t_prev < t``
        x_prev : (B, ...), the sample at level ``t_prev`` (the clean x₀ for ``t_prev = -1``).
        Returns :class:`StepOutput` ``(x_t, x0)`` (the field named ``x_prev`` holds x_t).
        """
        t = self._timesteps(t)
        t_prev = self._timesteps(t_prev, "t_prev", allow_final=True)
        if bool((t_prev >= t).any()):
            raise ValueError(f"t_prev must be smaller than t, got t={t.tolist()}, "
                             f"t_prev={t_prev.tolist()}")
        _check_finite(x_prev, "x_prev")
        _check_finite(model_output, "model_output")
        _check_same_shape(model_output, x_prev, "model_output", "x_prev")
        a_t = self._per_sample(self.alphas_cumprod[t], x_prev)
        a_p = self._per_sample(self._alpha_bar_prev(t_prev, self._final_alpha_cumprod()),
                               x_prev)
        kind = self.config.prediction_type
        if kind == "epsilon":
            eps = model_output
            x0 = (x_prev - (1 - a_p).sqrt() * eps) / a_p.sqrt()
        else:
            if kind == "sample":
                x0 = model_output
            else:                                    # v at level t_prev
                x0 = a_p.sqrt() * x_prev - (1 - a_p).sqrt() * model_output
            clean = (1 - a_p) < 1e-12                # x_prev is x₀: read ε̂ at level t
            a_e = torch.where(clean, a_t, a_p)
            eps = (x_prev - a_e.sqrt() * x0) / (1 - a_e).sqrt()
        x0 = self._clip(x0)
        return StepOutput(a_t.sqrt() * x0 + (1 - a_t).sqrt() * eps, x0)          # Eq. (17)

    def invert(self, model_fn: Callable[[torch.Tensor, torch.Tensor, Any], torch.Tensor],
               x0: torch.Tensor, steps: int = 50, cond: Any = None,
               progress: bool = False, fixed_point: int = 0) -> torch.Tensor:
        """Deterministic DDIM inversion of clean samples ``x0`` (B, ...) to the noise level of
        the first sampling step: :meth:`ddim_invert_step` along the timesteps of
        :meth:`set_timesteps` ``(steps)`` in ascending order (Sketch2Anim supp. D, z_T^Inv).
        ``model_fn(x, t, cond)`` as in :meth:`sample` (no classifier-free guidance: inversion
        with guidance drifts). Sampling the result with :meth:`sample` ``(steps, method=
        "ddim", x_T=...)`` and the same network returns ≈ x0, exactly in the limit of many
        steps for a network that is exact (tests: a Gaussian data model).

        ``fixed_point`` > 0 refines each step by that many fixed-point iterations that
        evaluate the network at the current estimate of x_t instead of at x_{t_prev}
        (Pan et al. 2023, "Effective real image editing with accelerated iterative diffusion
        inversion"). It converges where ε̂ is well conditioned; for an x̂₀-predicting network
        at nearly noise-free levels (1 − ᾱ ≈ 0.002 in MLD's "leading" schedule) ε̂ amplifies
        any x̂₀ error ~24x and the iteration diverges (measured on an exact Gaussian model,
        20 steps: round-trip error 0.63 / 2.1 / 35 for 0 / 1 / 3 refinements), so 0 is the
        default. From the clean level with ``set_alpha_to_one`` an x̂₀ / v network's first
        step returns its input unchanged (:meth:`ddim_invert_step`). The scheduler's
        timesteps are restored afterwards. Returns z (B, ...)."""
        _check_finite(x0, "x0")
        if isinstance(fixed_point, bool) or not isinstance(fixed_point, (int, np.integer)) \
                or fixed_point < 0:
            raise ValueError(f"fixed_point must be an integer >= 0, got {fixed_point!r}")
        previous = getattr(self, "timesteps", None), getattr(self, "num_inference_steps", None)
        timesteps = self.set_timesteps(steps).flip(0)                       # ascending
        x = x0
        B = x.shape[0]
        try:
            return self._invert_loop(model_fn, x, B, timesteps, cond, progress, fixed_point)
        finally:                                      # leave the sampling order as it was
            self.timesteps, self.num_inference_steps = previous

    def _invert_loop(self, model_fn, x, B, timesteps, cond, progress, fixed_point):
        with torch.no_grad():
            for i, t in enumerate(tqdm(timesteps.tolist(), disable=not progress,
                                       desc="DDIM inversion")):
                t_prev = int(timesteps[i - 1]) if i > 0 else -1
                t_in = torch.full((B,), t, dtype=torch.int64, device=x.device)
                x_t = x
                for _ in range(1 + int(fixed_point)):   # network at x_{t_prev}, then at x_t
                    out = model_fn(x_t, t_in, cond)
                    if not isinstance(out, torch.Tensor) or out.shape != x.shape:
                        raise ValueError(f"model_fn must return a tensor of shape "
                                         f"{tuple(x.shape)}, got "
                                         f"{getattr(out, 'shape', type(out).__name__)}")
                    x_t, _ = self.ddim_invert_step(out, t, t_prev, x)
                x = x_t
        return x

    # ------------------------------------------------------------------ sampling loop

    def sample(self, model_fn: Callable[[torch.Tensor, torch.Tensor, Any], torch.Tensor],
               shape: Sequence[int] | None, steps: int | None = None, method: str = "ddim",
               guidance_scale: float | None = None, cond: Any = None, uncond: Any = None,
               generator: torch.Generator | None = None, progress: bool = False,
               callback: Callable[[int, int, torch.Tensor, torch.Tensor], None] | None = None,
               eta: float = 0.0, x_T: torch.Tensor | None = None, device=None,
               dtype: torch.dtype = torch.float32) -> torch.Tensor:
        """Draw samples by running the reverse process from x_T ~ N(0, I).

        model_fn : ``model_fn(x_t, t, cond) -> output`` with x_t ``(B, ...)``, t a ``(B,)``
            int64 tensor (the same level for every sample), output shaped like x_t and of
            kind ``config.prediction_type``. It is called under ``torch.no_grad()``; one that
            needs gradients (Sketch2Anim's inference guidance, supp. Eq. (15)) opens
            ``torch.enable_grad()`` itself.
        shape : ``(B, ...)`` of the samples (may be None when ``x_T`` is given)
        steps : number of denoising steps; default 50 for DDIM, T for DDPM
        method : ``"ddim"`` (:meth:`ddim_step`, Sketch2Anim's sampler) or ``"ddpm"``
            (:meth:`ddpm_step`)
        guidance_scale : None for a single conditional call ``model_fn(x, t, cond)``; else w of
            Eq. (14), combining ``model_fn(x, t, uncond)`` and ``model_fn(x, t, cond)``
            (two calls per step; Sketch2Anim uses w = 7.5)
        cond, uncond : anything ``model_fn`` accepts (tensors, dicts, None)
        generator : torch.Generator for x_T and the step noise
        progress : show a tqdm bar; callback : ``callback(i, t, x_prev, x0_hat)`` after step i
        eta : DDIM η (0 = deterministic); x_T : optional starting noise ``(B, ...)``
        device, dtype : of the samples when ``x_T`` is not given
        Returns x₀, a tensor of ``shape``.
        """
        if method not in ("ddim", "ddpm"):
            raise ValueError(f"method must be 'ddim' or 'ddpm', got {method!r}")
        if steps is None:
            steps = 50 if method == "ddim" else self.num_train_timesteps
        # full-length DDPM visits every timestep T-1 .. 0 whatever the offset of the spacing
        full = method == "ddpm" and steps == self.num_train_timesteps
        timesteps = self.set_timesteps(steps, spacing="trailing" if full else None)  # (S,) desc.
        if (guidance_scale is not None
                and not bool(torch.isfinite(torch.as_tensor(guidance_scale)).all())):
            raise ValueError(f"guidance_scale must be finite or None, got {guidance_scale}")
        if x_T is None:
            if shape is None:
                raise ValueError("give the sample shape (B, ...) or a starting noise x_T")
            shape = tuple(int(s) for s in shape)
            if not shape or min(shape) < 1:
                raise ValueError(f"shape must be a non-empty tuple of positive sizes, got {shape}")
            x = torch.randn(shape, generator=generator, device=device, dtype=dtype)  # x_T ~ N(0, I)
        else:
            _check_finite(x_T, "x_T")
            if shape is not None and tuple(shape) != tuple(x_T.shape):
                raise ValueError(f"shape {tuple(shape)} does not match x_T of shape "
                                 f"{tuple(x_T.shape)}")
            x = x_T
        B = x.shape[0]

        with torch.no_grad():
            for i, t in enumerate(tqdm(timesteps.tolist(), disable=not progress,
                                       desc=f"{method} sampling")):
                t_prev = int(timesteps[i + 1]) if i + 1 < len(timesteps) else -1
                t_in = torch.full((B,), t, dtype=torch.int64, device=x.device)   # (B,)
                if guidance_scale is None:
                    out = model_fn(x, t_in, cond)
                else:
                    out_c = model_fn(x, t_in, cond)
                    out_u = model_fn(x, t_in, uncond)
                    out = classifier_free_guidance(out_u, out_c, guidance_scale)  # Eq. (14)
                if not isinstance(out, torch.Tensor) or out.shape != x.shape:
                    raise ValueError(f"model_fn must return a tensor of shape {tuple(x.shape)}, "
                                     f"got {getattr(out, 'shape', type(out).__name__)}")
                if method == "ddim":
                    x, x0_hat = self.ddim_step(out, t, t_prev, x, eta=eta, generator=generator)
                else:
                    x, x0_hat = self.ddpm_step(out, t, x, generator=generator, t_prev=t_prev)
                if callback is not None:
                    callback(i, t, x, x0_hat)
        return x
