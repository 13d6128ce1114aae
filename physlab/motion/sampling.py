"""Sampling from a trained motion generator (nanoGPT's ``sample.py``): action text + optional
keypose + optional joint trajectories -> a 40-frame motion ``(40, 22, 3)`` in metres.

Usage::

    from physlab.motion.sampling import Generator, generate
    gen = Generator.from_checkpoint("runs/control.pt")
    joints = gen("a person walks", keypose_3d=K, keypose_at="first",
                 trajectories_3d={"pelvis": P}, seed=0)                 # (40, 22, 3)
    joints = generate("a person walks")          # DEFAULT_CHECKPOINT, loaded once and cached

Any subset of conditions may be given (Sketch2Anim Fig. 13): text only, text + keypose,
text + trajectories, or all three.

* **Text only** runs the text denoiser ``eps_theta(x_t, t, a)`` alone (the frozen base of a
  control checkpoint, or a base checkpoint) — the pre-trained text-to-motion model.
* **Keypose / trajectories** need a control checkpoint (:class:`ControlledDenoiser`). The
  dense condition is laid out exactly as :func:`~physlab.motion.dataset.condition_from_window`
  does (Sketch2Anim Sec. 3): ``keypose_at="first"`` puts the keypose at frame 0 and each
  trajectory of ``t_r`` frames into frames ``0 .. t_r-1``; ``"last"`` puts the keypose at
  frame 39 and the trajectories into the last ``t_r`` frames. Joints without a trajectory
  are masked out. Training always pairs a keypose with >= 1 trajectory; a missing keypose is
  encoded as "no keypose": the adapter's grounded embedding is ``a' = a`` (``E_k(K) = 0``,
  the keypose branch adds nothing; for the single-ControlNet ablation a zero pose),
  a missing trajectory as an all-False mask. Both are outside the training distribution,
  so expect weaker control there than for keypose + trajectories.
* **Classifier-free guidance** (Sketch2Anim Eq. (14)), ``eps = eps_u + w (eps_c - eps_u)``,
  is applied to the *text*: ``eps_u`` replaces the action embedding by the learned null
  embedding (``drop_text``), ``eps_c`` uses it; the keypose / trajectory branches are active
  in *both* passes, so the control signal is not amplified by ``w`` (the two passes run as
  one batch of 2). ``w = 0`` is the text-free model, ``w = 1`` the plain conditional one.

Coordinates: the conditions live in the canonical window frame of training
(:func:`~physlab.motion.dataset.make_windows`): metres, y up, pelvis of frame 0 at
``x = z = 0`` facing ``+z``; the returned joints are in the same frame.

A checkpoint is the output of ``python -m physlab.motion.train`` (or its ``--export`` fp16
copy). Time per clip (1 CPU thread, 50 DDIM steps, CFG as one batch of 2): smoke model
~0.04 s text only / ~0.12 s with keypose + trajectory; default-size model (d_model 128, 4
layers) ~0.17 s text only / ~0.55 s controlled.
"""
from __future__ import annotations

import contextlib
import functools
import math
from pathlib import Path

import numpy as np
import torch

from .dataset import TRAJECTORY_JOINT_NAMES, TRAJECTORY_JOINTS
from .conditions import GUIDANCE_SPLIT  # noqa: F401 (re-exported with the builders below)
from .conditions import (KEYPOSE_AT, MAX_GUIDANCE, N_FRAMES, build_condition, build_sketch,
                         check_guidance, guidance_at)
from .diffusion import classifier_free_guidance
from .body import LEG_CHAINS, clip_bone_lengths, constrain_body
from .features import ABS_BODY, ABS_PATH, ABS_PELVIS, decode_motion, encode_motion
from .model import ControlledDenoiser, features_to_joints_torch, low_pass_matrix
from .skeleton import JOINT_NAMES, PARENTS

__all__ = ["DEFAULT_CHECKPOINT", "N_FRAMES", "Generator", "build_condition", "build_sketch",
           "generate", "load_generator"]

#: Default control checkpoint used by :func:`generate` (not shipped; train it, see below).
DEFAULT_CHECKPOINT = Path(__file__).resolve().parents[2] / "data" / "motion" / \
    "sketch2anim_control.pt"

METHODS = ("ddim", "ddpm")
#: The toe joints (left, right) whose trajectory frames :func:`~physlab.motion.body.lock_feet`
#: must not move.
FOOT_TOES = tuple(chain[3] for chain in LEG_CHAINS)


def _train_commands(path):
    return (f"`python -m physlab.motion.train --stage base --out runs/base.pt` then "
            f"`python -m physlab.motion.train --stage control --base-ckpt runs/base.pt "
            f"--out {path}` (add --smoke for a seconds-long test model)")


# ----------------------------------------------------------------------------- conditions


#: Default text guidance scale w of Eq. (14) without keypose / trajectories. Sketch2Anim uses
#: 7.5; for the shipped model 2.5 is better (8 actions x 2 seeds, text only: the nearest real
#: action is the one asked for in 62 % of clips against 44 % at 7.5; path speeds: walks 1.22
#: (7.5: 1.48) against 1.08 m/s real, walks backwards 1.41 (3.68) against 0.71; runs overshoot
#: at both, 4.7 / 3.9 against 2.1. ``python -m physlab.motion.evaluate --adherence``.
#: Re-measured 2026-11-29 with the attached text model (:attr:`Generator.text_model`), 32
#: clips per action: at w = 2 / 2.5 / 3 walks backwards +48 / +35 / +24 % of the real speed,
#: the wave's wrist travel 47 % of real at all three, held-out jerk AUJ 2.84x real at 2.5 and
#: 3.14x at 3 (issue 12's bound: 3x), so 2.5 stays.
TEXT_GUIDANCE = 2.5
#: Default text guidance scale with a keypose or trajectories (:meth:`Generator.__call__`).
CONTROL_TEXT_GUIDANCE = 1.0
#: DCT frequencies kept in x̂₀ at every sampling step of a smooth-basis model
#: (``DenoiserConfig.smooth_basis`` = 16 when trained), text only / under control
#: (:meth:`Generator.__call__` ``frequencies``). The model was trained to predict 16, but
#: its highest frequencies come out as jitter, not motion: on 16 held-out windows
#: text-only clips at 16 / 12 / 10 / 8 frequencies had jerk AUJ 1.72 / 0.38 / 0.30 / 0.48,
#: PJ 0.113 / 0.071 / 0.047 / 0.061 and foot skating 0.29 / 0.21 / 0.17 / 0.14 (real clips
#: 0.19, 0.046, 0.16); under control (networks only, 16 / 12 / 10) AUJ 0.51 / 0.29 / 0.30 at
#: the same trajectory error (0.094 / 0.095 / 0.096 m), and with the default guidance AUJ
#: 1.08 / 1.05 / 0.66, condition-edge step ratio 4.9 / 4.0 / 2.4, evaluator FID unchanged
#: within noise. ``python -m physlab.motion.evaluate --frequencies K``.
TEXT_FREQUENCIES = 10
CONTROL_FREQUENCIES = 10
#: DCT frequencies kept in the pelvis's horizontal path (x, z of the ``"absolute"`` features)
#: of a text-only clip (:meth:`Generator.__call__` ``path_frequencies``). The shipped model's
#: pelvis surges back and forth along its path (text-only runs: one-frame steps from -0.29 to
#: +0.59 m; horizontal pelvis acceleration 0.059 m/frame² against 0.008 in real runs), which
#: inflates the path speed (runs 2.7 m/s against 2.1 real, 8 seeds) though the travel is
#: right. Real 40-frame pelvis paths keep within 1.6–2.6 cm (mean) of their 6 lowest
#: frequencies (runs 2.6, walks 1.9, walks to the left 1.6 cm); measured with 6 / 8 / 10
#: (the rest), path speed runs 1.98 / 2.18 / 2.69 m/s (real 2.10), walks to the left
#: 0.82 / 0.98 / 1.13 (0.83), pelvis acceleration 0.021 / 0.036 / 0.059 (runs). Under
#: control the conditions say where the pelvis goes: the path keeps the model's frequencies.
PATH_FREQUENCIES = 6
#: Joints whose columns keep all :data:`TEXT_FREQUENCIES` in a text-only clip: the collars,
#: shoulders, elbows and wrists, which carry a wave (:data:`BODY_FREQUENCIES`).
ARM_JOINTS = ("left_collar", "right_collar", "left_shoulder", "right_shoulder", "left_elbow",
              "right_elbow", "left_wrist", "right_wrist")
#: DCT frequencies kept in the other joints' columns (legs, spine, head, relative to the
#: pelvis, and the pelvis height) of a text-only clip from an ``"absolute"``-feature model
#: (:meth:`Generator.__call__` ``body_frequencies``). The text model's legs and trunk carry
#: jitter in their 9th and 10th frequencies, which real legs barely use: projecting the real
#: windows of all 874 clips onto 8 instead of 10 frequencies moves those joints by 0.35 cm
#: more on average (0.93 against 0.58 cm) and leaves their jerk AUJ almost as it is (1.03
#: against 1.08), while the text model's held-out clips (64 windows, seed 0 / 128, seed 1;
#: ``evaluate --control data/motion/sketch2anim_control.pt``, 2026-11-29) go from jerk AUJ
#: 2.90 / 3.06x real to 2.66 / 2.13x and foot skating 1.48 / 1.45x to 1.21 / 1.13x, FID
#: 0.151 / 0.119 to 0.135 / 0.124, R-precision top-3 0.83 / 0.90 to 0.80 / 0.86, and the
#: text adherence (32 clips per text) moves by at most 2 % of the real speeds. With 7: AUJ
#: 2.08 / 1.82x, but FID 0.161 / 0.136. The arms keep 10: with all joints at 8 the AUJ is
#: 1.74x, but a wave is what the arms' higher frequencies carry.
BODY_FREQUENCIES = 8
#: Weight λ_b of the bone-length term of the x̂₀ guidance (:meth:`Generator._guide`): the
#: optimisation keeps every bone at its keypose (or pre-guidance median) length, so it
#: re-poses the body instead of stretching a limb that the rigid-bone projection then pulls
#: off its target. On 64 held-out windows with the default guidance, λ_b = 0 / 3 / 10 / 30 /
#: 100: trajectory error 0.033 / 0.013 / 0.013 / 0.013 / 0.014 m, AUJ 0.49 / 0.18 / 0.18 /
#: 0.19 / 0.20, PJ 0.097 / 0.054 / 0.043 / 0.043 / 0.042 (real clips 0.26, 0.047), foot
#: skating 0.21 / 0.22 / 0.23 / 0.24 / 0.26, largest condition-edge step ratio 3.2 / 3.2 /
#: 3.1 / 3.3 / 3.6.
GUIDANCE_BONES = 10.0
#: Weight λ_e and bound c_e of the condition-edge term of the x̂₀ guidance
#: (:meth:`Generator._guide`): at each frame where a (3D or drawn) trajectory starts or ends,
#: every joint's step beyond ``c_e`` times the pre-guidance clip's median step (of the largest
#: joint step per frame) is penalised, ``λ_e · Σ_j (‖Δx_{k,j}‖ − c_e s̃)₊²`` (m²). Issue 12
#: asks for no joint step above 3× the median there; the guidance otherwise moves a fast foot
#: swing of the network's onto the frame where a foot stroke ends (a slow walk: 5.7×).
GUIDANCE_EDGES, EDGE_STEP = 10.0, 2.5

#: Default DDIM steps of :meth:`Generator.__call__` / :func:`generate`. Sketch2Anim samples
#: with 50. Measured with `python -m physlab.motion.evaluate --steps N` (2026-11-28):
#:
#: * shipped control model, 64 held-out windows (Cross protocol), 40 / 25 / 20 steps:
#:   networks-only trajectory error 0.0830 / 0.0836 / 0.0846 m, FID 0.106 / 0.107 / 0.111;
#:   guided trajectory error 0.0124 m at all three, FID 0.093 / 0.093 / 0.095, condition-edge
#:   step ratio 2.62 / 2.65 / 2.57; text-only FID 0.142 at all three;
#: * the balanced skip base, text only, 16 clips per action text (``--adherence``), 40 / 25:
#:   pelvis speeds within 0.01 m/s for every action, wrist travel within 0.002 m/frame,
#:   recognised 73 % / 73 %, jerk AUJ 2.64 / 2.57.
#:
#: 25 steps keep the clips' quality (20 begin to lose it) at 5/8 of the time of 40 (earlier:
#: 40 matched 50). The README's tables before 2026-11-28 were measured at 50 steps.
DEFAULT_STEPS = 25

#: Where the per-step inference guidance optimises (:meth:`Generator.__call__`).
GUIDANCE_SPACES = ("x0", "network")
#: How it optimises: L-BFGS (Sketch2Anim) or first-order Adam steps.
GUIDANCE_OPTIMIZERS = ("lbfgs", "gradient")
#: Adam learning rate of the first-order guidance per space: on x̂₀ in feature units (m),
#: on ``z_t`` in noise units.
FIRST_ORDER_LR = {"x0": 0.01, "network": 0.05}


def _minimise(closure, params, iters, optimizer, lr=0.01):
    """``iters`` L-BFGS iterations (strong Wolfe line search) or Adam steps of size ``lr`` on
    ``closure`` (which zeroes the gradients, evaluates the loss and calls ``backward``)."""
    if optimizer == "lbfgs":
        opt = torch.optim.LBFGS(params, lr=1.0, max_iter=int(iters), history_size=10,
                                line_search_fn="strong_wolfe")
        opt.step(closure)
        return
    opt = torch.optim.Adam(params, lr=lr)
    for _ in range(int(iters)):
        closure()
        opt.step()


def _condition_edges(cond, sketch):
    """(k,) long tensor of the steps ``i -> i + 1`` where a 3D or drawn trajectory condition
    starts or ends (any of the six joints; :func:`~physlab.motion.metrics.boundary_step_ratio`
    measures the same steps)."""
    masks = [d["traj_mask"][0].any(-1) for d in (cond, sketch) if d is not None]
    if not masks:
        return torch.zeros(0, dtype=torch.long)
    m = torch.stack(masks).any(0)                                            # (N,)
    return torch.nonzero(m[1:] != m[:-1]).flatten()


def _progress(items, show, desc):
    """``items`` wrapped in a tqdm bar when ``show``."""
    if not show:
        return items
    from tqdm.auto import tqdm

    return tqdm(items, desc=desc, leave=False)


# ----------------------------------------------------------------------------- generator


class Generator:
    """A loaded checkpoint, ready to sample.

    Attributes
    ----------
    model : :class:`MotionDenoiser` (base checkpoint) or :class:`ControlledDenoiser`, eval.
    scheduler : :class:`~physlab.motion.diffusion.NoiseScheduler`.
    stats : :class:`~physlab.motion.features.FeatureStats` (de-normalisation).
    text_cache : :class:`~physlab.motion.text.EmbeddingCache`; known action texts never load
        the text encoder (``text_cache.n_encoded`` counts encoded texts).
    stage : ``"base"`` | ``"control"``; path : Path of the checkpoint.
    fused : bool (default True), run a control model's network as a
        :class:`~physlab.motion.model.FusedControlledDenoiser` (:meth:`_controlled`); False:
        the model's own forward (the same numbers to float rounding, slower).
    text_model : None or a :class:`MotionDenoiser` that samples the text-only requests of
        :meth:`__call__` (no keypose, trajectories or drawing) in place of the control model's
        frozen base (:func:`~physlab.motion.checkpoint.attach_text_model`: physlab's
        deviation from Sketch2Anim, which samples text only from the ControlNet's base). The
        shipped checkpoint has one; set it to None for the paper's behaviour.
    text_stats : None or the :class:`~physlab.motion.features.FeatureStats` the text model
        was trained with, where they differ from ``stats`` (a text base with a finer pelvis
        path scale, ``train --pelvis-scale``); None: ``stats``. :attr:`stats` gives them
        while the text model samples.
    text_model_guidance : None, a float or a pair ``(w_high, w_low)``, the text model's own
        default text guidance scale (``attach-text --guidance``); :attr:`text_guidance`.
    """

    def __init__(self, model, scheduler, stats, text_cache, stage, path=None, text_model=None,
                 text_stats=None, text_model_guidance=None):
        self.model, self.scheduler, self._stats = model, scheduler, stats
        self.text_cache, self.stage, self.path = text_cache, stage, path
        self.config = model.config
        self.text_model, self.text_stats = text_model, text_stats
        self.text_model_guidance = text_model_guidance
        self.train_takes = ()   # Bandai-Namco takes trained on, when the checkpoint says
        self.fused = True
        self._fused, self._modules = None, []
        self._text_active = False

    @classmethod
    def from_checkpoint(cls, path):
        """Load a checkpoint of :func:`physlab.motion.train.train` (or its fp16 export).

        FileNotFoundError (with the training commands) if the file is missing, ValueError if
        it is truncated / corrupt / not a physlab motion checkpoint / lacks sampling data."""
        from .checkpoint import load_checkpoint, load_model
        from .text import hash_encoder

        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no motion checkpoint at {path}; make one with "
                                    f"{_train_commands(path)}")
        ckpt = load_checkpoint(path)            # ValueError: corrupt / wrong kind / version
        missing = sorted({"stage", "model_config", "model", "scheduler", "feature_stats",
                          "text_cache"} - set(ckpt))
        if missing:
            raise ValueError(f"{path} lacks {missing}; it was not written by "
                             f"physlab.motion.train: retrain with {_train_commands(path)}")
        try:
            loaded = load_model(ckpt)
        except (RuntimeError, KeyError, TypeError) as e:
            raise ValueError(f"{path}: the weights do not fit the saved model config "
                             f"({type(e).__name__}: {e}); retrain with "
                             f"{_train_commands(path)}") from None
        except ValueError as e:                 # e.g. a bad text_model.guidance
            raise ValueError(f"{path}: {e}") from None
        cache = loaded["text_cache"]
        if (ckpt.get("train_config") or {}).get("text_encoder") == "hash":
            cache.encoder = hash_encoder        # smoke / test models: the fake encoder
        gen = cls(loaded["model"], loaded["scheduler"], loaded["stats"], cache,
                  loaded["stage"], path, text_model=loaded["text_model"],
                  text_stats=loaded["text_stats"],
                  text_model_guidance=loaded["text_guidance"])
        gen.train_takes = tuple(ckpt.get("train_takes") or ())    # () = not recorded
        return gen

    def __repr__(self):
        return (f"Generator(stage={self.stage!r}, path={str(self.path)!r}, "
                f"d_model={self.config.d_model}, n_layers={self.config.n_layers}, "
                f"text_model={self.text_model is not None})")

    @property
    def text_guidance(self):
        """Default text guidance scale w of text-only requests (:meth:`__call__` with
        ``guidance_scale=None``): the attached :attr:`text_model`'s own when it has one
        (:func:`~physlab.motion.checkpoint.attach_text_model` ``guidance``), else
        :data:`TEXT_GUIDANCE` (also when :attr:`text_model` is set to None: the frozen base
        then samples)."""
        if self.text_model is not None and self.text_model_guidance is not None:
            return self.text_model_guidance
        return TEXT_GUIDANCE

    @property
    def has_control(self):
        """True if the checkpoint accepts keypose / trajectory conditions."""
        return isinstance(self.model, ControlledDenoiser)

    @property
    def has_sketch_encoders(self):
        """True if the checkpoint has the aligned 2D encoders of Sec. 5 (stage ``align``):
        drawn conditions then go through the network, not only through the guidance."""
        return self.has_control and self.model.has_sketch_encoders

    def _sketch_condition(self, cond, c, sk, camera):
        """The network's condition for a drawing (:meth:`~physlab.motion.model.
        ControlledDenoiser.condition_embeddings`): the 3D dict ``cond`` plus the drawn
        keypose and trajectories and the camera. 3D trajectories of other joints are projected
        into the drawing (``E^2D_tr`` reads one picture; the guidance still holds them in
        3D); a 3D keypose keeps the 3D keypose encoder."""
        out = dict(cond)
        out["camera"] = torch.tensor([[camera.scale, camera.pitch, camera.yaw, camera.roll]],
                                     dtype=torch.float32)
        if sk["has_trajectory"]:
            traj, mask = sk["trajectory"].copy(), sk["traj_mask"].copy()
            m3 = c["traj_mask"]
            if m3.any():
                traj[m3] = camera.project(c["trajectory"][m3])
                mask |= m3
            out["trajectory_2d"] = torch.tensor(traj, dtype=torch.float32)[None]
            out["traj_mask_2d"] = torch.tensor(mask)[None]
        if sk["has_keypose"]:
            out["keypose_2d"] = torch.tensor(sk["keypose"], dtype=torch.float32)[None]
            out["keypose_mask"] = torch.tensor([True])
        return out

    @contextlib.contextmanager
    def _frequencies(self, k, path=None, body=None):
        """Inside the block the denoiser's output basis keeps ``k`` DCT frequencies (None:
        unchanged), the pelvis's horizontal path (the ``"absolute"`` features' pelvis x
        and z) only its ``path`` lowest, and the pelvis height and the joints other than
        :data:`ARM_JOINTS` only their ``body`` lowest (None: as the rest)."""
        base = self.denoiser
        old, old_cols = base.low_pass, base.column_low_pass
        if k is not None and old is not None and k != self.config.smooth_basis:
            base.low_pass = low_pass_matrix(self.config.n_frames, int(k)).to(old)
        passes = []
        if path is not None:
            mask = torch.zeros(self.config.feature_dim)
            mask[list(ABS_PATH)] = 1.0                                        # pelvis x, z
            passes.append((mask, low_pass_matrix(self.config.n_frames, int(path))))
        if body is not None:
            mask = torch.zeros(self.config.feature_dim)
            mask[ABS_PELVIS.start + 1] = 1.0                                 # pelvis height
            for j, name in enumerate(JOINT_NAMES[1:]):                       # joint - pelvis
                if name not in ARM_JOINTS:
                    mask[ABS_BODY.start + 3 * j: ABS_BODY.start + 3 * j + 3] = 1.0
            passes.append((mask, low_pass_matrix(self.config.n_frames, int(body))))
        if passes:
            base.column_low_pass = tuple(passes)
        try:
            yield
        finally:
            base.low_pass, base.column_low_pass = old, old_cols

    @property
    def denoiser(self):
        """The text-only denoiser: the frozen base of a control model (the model itself for a
        base checkpoint), or :attr:`text_model` inside :meth:`_using_text_model`."""
        if self._text_active:
            return self.text_model
        return self.model.base if self.has_control else self.model

    @property
    def stats(self):
        """The feature statistics of the network sampling now: :attr:`text_stats` inside
        :meth:`_using_text_model` if the text model has its own, else the checkpoint's."""
        if self._text_active and self.text_stats is not None:
            return self.text_stats
        return self._stats

    @contextlib.contextmanager
    def _using_text_model(self, on):
        """Inside the block :attr:`denoiser` is :attr:`text_model` if ``on`` (and there is
        one)."""
        old = self._text_active
        self._text_active = bool(on) and self.text_model is not None
        try:
            yield
        finally:
            self._text_active = old

    # -- network evaluation

    def _controlled(self, x, t, a, cond, drop):
        """The controlled network's output, Eq. (4), by a :class:`~physlab.motion.model.
        FusedControlledDenoiser` (the blocks of one depth of the ControlNet copy, the adapter
        copy and the base as one batched computation: the same numbers to float rounding, a
        networks-only clip in 0.66–0.84x the time on one thread, ``benchmarks/bench_motion.py``).
        Made at the first call, and again if :attr:`model` is replaced; it follows weight
        changes itself. With :attr:`fused` False, or any module in training mode, the model's
        own forward runs."""
        if not self.fused:
            return self.model(x, t, a, cond, drop)
        if self._fused is None or self._fused.model is not self.model:
            from .model import FusedControlledDenoiser
            self._fused = FusedControlledDenoiser(self.model)
            # walking the module tree at every step cost ~3 % of a guided clip
            self._modules = list(self.model.modules())
        if any(m.training for m in self._modules):
            return self.model(x, t, a, cond, drop)
        return self._fused(x, t, a, cond, drop)

    @staticmethod
    def _pairs(timesteps):
        """``(t, t_prev)`` along a descending schedule; ``t_prev = -1`` after the last."""
        ts = [int(t) for t in timesteps]
        return list(zip(ts, ts[1:] + [-1]))

    def _decode(self, x0):
        """The (1, T, D) normalised clean estimate x̂₀ -> (de-normalised (T, D) features,
        (N, 22, 3) joints)."""
        feats = self.stats.denormalize(x0[0].double().numpy())
        return feats, decode_motion(feats, self.config.representation)

    def _eps(self, x, t, a, drop, cond):
        """Network output (B, T, D) (x̂₀ / ε̂ / v̂, the scheduler's ``prediction_type``) of the
        text model (cond None) or the controlled one (Eq. (4); a sample whose
        ``cond["keypose_mask"]`` is False gets ``a' = a``, Eq. (2) with ``E_k(K) = 0``)."""
        if cond is None:
            return self.denoiser(x, t, a, drop)
        return self._controlled(x, t, a, cond, drop)

    def _predict(self, x, t, a, cond, w, w_c=1.0):
        """The network output of one denoising step with classifier-free guidance, Eq. (14).

        Text only (``cond`` None): ``out_∅ + w (out_a − out_∅)`` (null text vs. the action;
        both in one batch of 2). With a keypose / trajectories, guidance on each condition in
        turn (compositional CFG): ``out_∅ + w (out_a − out_∅) + w_c (out_{a,K,T} − out_a)``,
        where ``out_a`` is the text model and ``out_{a,K,T}`` the controlled one. The second
        term is Sketch2Anim's Eq. (14) — its "unconditional" pass keeps the action and drops the
        sketch — so ``w_c > 1`` pushes the motion further towards the keypose and trajectories;
        ``w`` = 1 leaves the text unguided (the paper's choice under control)."""
        one = torch.tensor([False])
        if cond is not None and w == 1.0 and w_c == 1.0:
            return self._controlled(x, t, a, cond, one)                     # out_{a,K,T}
        if w == 1.0:
            out_a = text = self.denoiser(x, t, a, one)
        else:
            out = self.denoiser(x.expand(2, -1, -1), t.expand(2), a.expand(2, -1),
                                torch.tensor([True, False]))                # (2, T, D)
            out_a = out[1:]
            text = classifier_free_guidance(out[:1], out_a, w)              # Eq. (14), text
        if cond is None:
            return text
        controlled = self._controlled(x, t, a, cond, one)                   # out_{a,K,T}
        return text + w_c * (controlled - out_a)                            # Eq. (14), sketch

    def _guide(self, out, x, t, cond, joints_target, iters, proximity, optimizer="lbfgs",
               sketch=None, loss_fn=None):
        """Inference guidance (Sketch2Anim supp. C, Eq. (15); loss-guided diffusion): ``iters``
        L-BFGS iterations on the clean-motion estimate x̂₀ of this step, minimising
        ``G(x) = L_tr(R(x)) + L_key(R(x)) + proximity · mean_j ‖R(x)_j − R(x̂₀)_j‖²
        + λ_b · mean_{t,j} (‖R(x)_{t,j} − R(x)_{t,p(j)}‖ − L_j)²`` (Eqs. (6), (8) on the decoded
        joints, metres²; the proximity term, the mean squared displacement of the joints, keeps
        the motion near the network's whatever the feature scaling; the bone term,
        :data:`GUIDANCE_BONES`, keeps each bone at the keypose's length ``L_j``, or at its
        median over the pre-guidance clip; the edge term, :data:`GUIDANCE_EDGES`, keeps every
        joint's step where a trajectory starts or ends below :data:`EDGE_STEP` times the
        clip's median step), then the network output is rewritten for the corrected x̂₀ so
        the sampler's step uses it. A ``sketch`` (2D conditions, see
        :func:`~physlab.motion.guidance.sketch_losses`) adds ``G`` of Eq. (16) and its keypose
        term. ``loss_fn(joints) -> scalar`` (joints ``(1, N, 22, 3)`` m, canonical frame) adds
        any other term to G (motion blending's ``G_m``, supp. Eq. (18)).

        The paper differentiates G through the network w.r.t. z_t and applies it only to its
        2D trajectories; physlab differentiates w.r.t. x̂₀ (no backpropagation through the
        network: ~10x cheaper on a CPU) and guides the 3D trajectories and the keypose; for a
        model with a low-pass output basis (``DenoiserConfig.smooth_basis``) the corrected x̂₀
        stays in that basis, so the guidance cannot add a jump where a stroke ends;
        :meth:`_guide_network` is the paper's form. ``optimizer="gradient"``: ``iters`` Adam
        steps (lr :data:`FIRST_ORDER_LR`) instead of L-BFGS, the first-order variant of Table
        A3."""
        from .guidance import joint_control_losses, sketch_losses

        sched = self.scheduler
        x0, _ = sched.split_output(out, x, t)
        mean = torch.as_tensor(self.stats.mean, dtype=x0.dtype)
        std = torch.as_tensor(self.stats.std, dtype=x0.dtype)
        ref = x0.detach()
        # optimise the de-normalised features u (metres, radians): the losses are in metres,
        # and in normalised units a column with a small std (e.g. the pelvis height) would
        # need a huge step for a small gradient (L-BFGS converged 30x slower there)
        u = (ref * std + mean).requires_grad_(True)
        rep = self.config.representation

        def decode(v):                                                       # (1, N, 22, 3) m
            return features_to_joints_torch(v * std + mean, representation=rep)

        ref_joints = decode(ref)
        has_key = cond is not None and bool(cond["keypose_mask"].any())
        child = torch.arange(1, len(PARENTS))
        parent = torch.as_tensor(np.array(PARENTS[1:]))

        def bones(j):                                                        # (1, N, 21) m
            return (j[..., child, :] - j[..., parent, :]).norm(dim=-1)

        bone_target = (bones(joints_target[1][:, int(cond["key_frame"][0])])[:, None]
                       if has_key else bones(ref_joints).median(dim=1, keepdim=True).values)

        target_tr, target_key = joints_target if joints_target is not None else (None, None)
        has_traj = cond is not None and bool(cond["traj_mask"].any())
        edges = _condition_edges(cond, sketch)
        step_cap = EDGE_STEP * (ref_joints[0, 1:] - ref_joints[0, :-1]).norm(dim=-1).max(
            dim=-1).values.median()

        def steps(j):                                                        # (k, 22) m
            return (j[0, edges + 1] - j[0, edges]).norm(dim=-1)

        smooth = self.denoiser.smooth       # keep the correction in the model's output basis

        def closure():
            u.grad = None
            z = smooth((u - mean) / std)
            joints = decode(z)
            g = proximity * ((joints - ref_joints) ** 2).sum(-1).mean()
            if GUIDANCE_BONES:                          # keep the bones: re-plan, don't drag
                g = g + GUIDANCE_BONES * ((bones(joints) - bone_target) ** 2).mean()
            if GUIDANCE_EDGES and len(edges):           # no jump where a stroke starts / ends
                g = g + GUIDANCE_EDGES * ((steps(joints) - step_cap).clamp(min=0) ** 2).sum()
            if has_traj:
                g = g + joint_control_losses(joints, target_tr, cond)[0]      # Eq. (6)
            if has_key:
                g = g + joint_control_losses(joints, target_key, cond)[1]     # Eq. (8)
            if sketch is not None:
                g = g + sum(sketch_losses(joints, sketch))                     # Eq. (16)
            if loss_fn is not None:
                g = g + loss_fn(joints)
            g.backward()
            return g

        with torch.enable_grad():
            _minimise(closure, [u], iters, optimizer, FIRST_ORDER_LR["x0"])
        x0g = smooth((u - mean) / std).detach()
        kind = sched.config.prediction_type
        if kind == "sample":
            return x0g
        eps = sched.predict_eps(x, x0g, t)
        if kind == "epsilon":
            return eps
        a = sched.alphas_cumprod[t].to(x.dtype).reshape(-1, *([1] * (x.ndim - 1)))
        return a.sqrt() * eps - (1 - a).sqrt() * x0g                      # v

    def _guide_network(self, x, t, a, cond, w, joints_target, iters, optimizer="lbfgs",
                       w_c=1.0, sketch=None, net_cond=None, loss_fn=None):
        """Sketch2Anim's inference guidance (supp. C, Eq. (15), in 3D): move the noisy sample
        ``z_t`` itself so that the network's clean estimate ``x̂₀(z_t)`` meets the conditions,
        ``z_t ← argmin G(x̂₀(z_t))`` by ``iters`` L-BFGS iterations (or Adam steps) with
        gradients through the network, then predict again from the new ``z_t``. The network
        re-plans the whole body around the targets (no joint is dragged alone), at the cost
        of one forward and backward pass per iteration. ``net_cond``: the condition the
        network sees, if it differs from the 3D ``cond`` the losses read (a drawing through the
        2D encoders); ``loss_fn(joints)`` adds a term on the decoded joints (as in
        :meth:`_guide`). Returns ``(z_t, network output)``."""
        from .guidance import joint_control_losses, sketch_losses

        mean = torch.as_tensor(self.stats.mean, dtype=x.dtype)
        std = torch.as_tensor(self.stats.std, dtype=x.dtype)
        rep = self.config.representation
        target_tr, target_key = joints_target if joints_target is not None else (None, None)
        has_traj = cond is not None and bool(cond["traj_mask"].any())
        has_key = cond is not None and bool(cond["keypose_mask"].any())
        z = x.detach().clone().requires_grad_(True)
        net_cond = cond if net_cond is None else net_cond

        def closure():
            z.grad = None
            x0, _ = self.scheduler.split_output(self._predict(z, t, a, net_cond, w, w_c), z, t)
            g = z.new_zeros(())
            joints = features_to_joints_torch(x0 * std + mean, representation=rep)  # R(x̂₀)
            if has_traj:
                g = g + joint_control_losses(joints, target_tr, cond)[0]        # Eq. (6)
            if has_key:
                g = g + joint_control_losses(joints, target_key, cond)[1]       # Eq. (8)
            if sketch is not None:                                           # Eq. (16)
                g = g + sum(sketch_losses(joints, sketch))
            if loss_fn is not None:
                g = g + loss_fn(joints)
            g.backward()
            return g

        with torch.enable_grad():
            _minimise(closure, [z], iters, optimizer, FIRST_ORDER_LR["network"])
        z = z.detach()
        return z, self._predict(z, t, a, net_cond, w, w_c)

    def _column_frequencies(self, name, value, default, absolute, kept):
        """``path_frequencies`` / ``body_frequencies`` of :meth:`__call__` checked: None gives
        ``min(default, kept)`` (``default`` None: no column low-pass)."""
        if value is None:
            return None if default is None else min(default, kept)
        if not absolute:
            raise ValueError(f"{name} must be None: {self.path} has no low-pass basis over "
                             f"'absolute' features (representation "
                             f"{self.config.representation!r}, smooth_basis "
                             f"{self.config.smooth_basis})")
        if (isinstance(value, bool) or not isinstance(value, (int, np.integer))
                or not 1 <= value <= kept):
            raise ValueError(f"{name} must be None or an integer in 1..{kept} (at most the "
                             f"frequencies kept), got {value!r}")
        return value

    def __call__(self, action, keypose_3d=None, keypose_at="first", trajectories_3d=None,
                 seed=0, guidance_scale=None, steps=None, method="ddim", return_features=False,
                 progress=False, inference_guidance=0, guidance_final=40,
                 guidance_proximity=0.01, body_constraints=True, guidance_space="x0",
                 guidance_optimizer="lbfgs", condition_scale=1.0, foot_lock=True,
                 frequencies=None, keypose_2d=None, trajectories_2d=None, camera=None,
                 sketch_encoders=True, path_frequencies=None, body_frequencies=None):
        """Generate one 40-frame motion.

        Parameters
        ----------
        action : str, the action text (e.g. ``"a person walks"``); a text outside the
            checkpoint's cache is encoded (loads the text encoder once).
        keypose_3d : None or (22, 3) array (m, canonical frame), pose at the key frame.
        keypose_at : ``"first"`` | ``"last"``: key frame 0 or 39, trajectories over the first
            / last ``t_r`` frames (:func:`build_condition`).
        trajectories_3d : None or dict ``{joint_name: (t_r, 3) array}`` (m), joint names from
            :data:`~physlab.motion.dataset.TRAJECTORY_JOINT_NAMES`, ``t_r <= 40``.
        seed : int, seeds x_T and (DDPM) the step noise.
        guidance_scale : None, float >= 0 or a pair ``(w_high, w_low)``
            (:data:`GUIDANCE_SPLIT`), w of Eq. (14) on the text (module docstring).
            None: :attr:`text_guidance` for text only, :data:`CONTROL_TEXT_GUIDANCE` when a
            keypose or trajectories are given (Sketch2Anim's Eq. (14) keeps the action word in
            both passes, so under control the text is not extrapolated; measured here, a text
            scale of 7.5 under control pushed the walks past their trajectories: networks-only
            trajectory error 0.31 m against 0.22 m at w = 1, 16 held-out windows).
        condition_scale : float >= 0, w_c of Eq. (14) on the keypose and trajectories
            (:meth:`_predict`; Sketch2Anim's form of the equation); 1 = the controlled
            network as it is, 0 = ignore the conditions.
        steps : None (:data:`DEFAULT_STEPS`, 25) or int >= 1, denoising steps; method :
            ``"ddim"`` (η = 0) | ``"ddpm"``.
        return_features : also return the (39, 137) de-normalised features.
        progress : tqdm bar over the steps.
        inference_guidance : int >= 0, L-BFGS iterations of inference guidance
            (:meth:`_guide`) at every denoising step but the last when a keypose or
            trajectories are given (Sketch2Anim: 4); default 0, see ``guidance_final``.
        guidance_final : int >= 0, L-BFGS iterations of the guidance at the last step, whose
            x̂₀ is the result: a post-optimisation, as the paper calls its guidance. Measured
            on 8 held-out windows with the shipped checkpoint: no guidance 0.34 m trajectory
            error / 0.47 m keypose MPJPE; 20 final iterations 0.047 / 0.031 m; 4 per step +
            20 final 0.042 / 0.031 m; 40 final 0.018 / 0.018 m. Default 40; set both to 0 for
            the ControlNet and adapter alone.
        guidance_proximity : float >= 0, weight of the stay-near-x̂₀ term of the guidance.
        guidance_space : ``"x0"`` (optimise the clean estimate, :meth:`_guide`: cheap) or
            ``"network"`` (optimise ``z_t`` through the network, :meth:`_guide_network`: the
            paper's form) for the per-step ``inference_guidance``; the final post-optimisation
            always works on x̂₀.
        guidance_optimizer : ``"lbfgs"`` or ``"gradient"`` (Adam steps; Table A3's
            first-order variant) for ``inference_guidance``.
        body_constraints : bool, project the clip onto rigid bones and lift feet that sink
            into the floor (:func:`~physlab.motion.body.constrain_body`; bone lengths from
            the keypose when one is given, else the clip's median lengths). The features
            returned with ``return_features`` are the network's, before this projection.
        foot_lock : bool, with ``body_constraints``: keep each foot still while it touches
            the ground and let the knee follow (:func:`~physlab.motion.body.lock_feet`); the
            keypose frame, and the frames where the guidance puts a foot on its trajectory
            condition, are left as they are. Without guidance the networks' toe only nears
            its stroke, so the lock holds it like any planted foot (measured on the 64
            held-out windows of ``python -m physlab.motion.evaluate``, networks only:
            foot skating 0.228 -> 0.179, trajectory error 0.100 -> 0.101 m, AUJ 0.17 -> 0.34;
            real clips 0.153 / 0.26).
        frequencies : None or an int ``1 <= K' <= K`` for a model with a low-pass output
            basis of ``K`` DCT frequencies: x̂₀ keeps only its ``K'`` lowest at every step
            (and so does the guidance). None = :data:`TEXT_FREQUENCIES` for text only,
            :data:`CONTROL_FREQUENCIES` under control (capped at ``K``).
        path_frequencies : None or an int ``1 <= K'' <= K'``: the pelvis's horizontal path
            keeps only its ``K''`` lowest (an ``"absolute"``-feature model). None =
            :data:`PATH_FREQUENCIES` for text only (the shipped model's pelvis surges along
            its path otherwise), the path as the rest under control or with a sketch.
        body_frequencies : None or an int ``1 <= K''' <= K'``: the pelvis height and the
            joints other than :data:`ARM_JOINTS` (legs, spine, head; relative to the pelvis)
            keep only their ``K'''`` lowest (an ``"absolute"``-feature model). None =
            :data:`BODY_FREQUENCIES` for text only (the text model's legs jitter otherwise),
            as the rest under control or with a sketch.
        keypose_2d, trajectories_2d, camera : a sketch (:func:`build_sketch`): a (22, 2)
            keypose and/or ``{joint_name: (t_r, 2)}`` trajectories in the normalised image
            coordinates of ``camera`` (:class:`~physlab.motion.camera.Camera`), placed like
            the 3D ones by ``keypose_at``. A checkpoint with the aligned 2D encoders of
            Sec. 5 (:attr:`has_sketch_encoders`) feeds them to the ControlNet and adapter
            (:meth:`_sketch_condition`), and the inference guidance (Eqs. (15)–(16), with a 2D
            keypose term) sharpens them; without the encoders they act through the guidance
            only, so they need ``guidance_final`` or ``inference_guidance`` > 0. They may be
            mixed with 3D conditions of other joints.
        sketch_encoders : bool, let the 2D encoders read a drawing when the checkpoint has
            them (False: guidance only, for comparisons).

        Returns
        -------
        (40, 22, 3) float64 joints in metres (and (39, 137) float64 features if asked).
        """
        if not isinstance(action, str) or not action.strip():
            raise ValueError(f"action must be a non-empty text such as 'a person walks', got "
                             f"{action!r}")
        if keypose_at not in KEYPOSE_AT:
            raise ValueError(f"keypose_at must be 'first' or 'last', got {keypose_at!r}")
        if guidance_scale is None:
            read_2d = bool(self.has_sketch_encoders and sketch_encoders
                           and (keypose_2d is not None or trajectories_2d))
            guidance_scale = (CONTROL_TEXT_GUIDANCE if keypose_3d is not None
                              or trajectories_3d or read_2d else self.text_guidance)
        guidance_scale = check_guidance(guidance_scale)
        if steps is None:
            steps = DEFAULT_STEPS
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise ValueError(f"steps must be an integer >= 1 (e.g. 50 DDIM steps), got "
                             f"{steps!r}")
        if method not in METHODS:
            raise ValueError(f"method must be 'ddim' or 'ddpm', got {method!r}")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise TypeError(f"seed must be an int, got {seed!r}")
        if not 0 <= seed < 2**63:
            raise ValueError(f"seed must be an integer in [0, 2**63) (torch's seed range), got "
                             f"{seed}")
        if (isinstance(inference_guidance, bool)
                or not isinstance(inference_guidance, (int, np.integer)) or inference_guidance < 0):
            raise ValueError(f"inference_guidance must be an integer >= 0 (L-BFGS iterations per "
                             f"step; 0 = off), got {inference_guidance!r}")
        if (isinstance(guidance_final, bool) or not isinstance(guidance_final, (int, np.integer))
                or guidance_final < 0):
            raise ValueError(f"guidance_final must be an integer >= 0, got {guidance_final!r}")
        if not (isinstance(guidance_proximity, (int, float)) and math.isfinite(guidance_proximity)
                and guidance_proximity >= 0):
            raise ValueError(f"guidance_proximity must be a finite number >= 0, got "
                             f"{guidance_proximity!r}")
        if (isinstance(condition_scale, bool) or not isinstance(condition_scale, (int, float))
                or not math.isfinite(condition_scale) or not 0 <= condition_scale <= MAX_GUIDANCE):
            raise ValueError(f"condition_scale must be a number in [0, {MAX_GUIDANCE:g}] (w_c of "
                             f"Eq. (14); 1 = no extra push), got {condition_scale!r}")
        if guidance_space not in GUIDANCE_SPACES:
            raise ValueError(f"guidance_space must be one of {GUIDANCE_SPACES}, got "
                             f"{guidance_space!r}")
        if guidance_optimizer not in GUIDANCE_OPTIMIZERS:
            raise ValueError(f"guidance_optimizer must be one of {GUIDANCE_OPTIMIZERS}, got "
                             f"{guidance_optimizer!r}")
        if not isinstance(body_constraints, (bool, np.bool_)):
            raise TypeError(f"body_constraints must be True or False, got {body_constraints!r}")
        if not isinstance(foot_lock, (bool, np.bool_)):
            raise TypeError(f"foot_lock must be True or False, got {foot_lock!r}")
        N = self.config.n_joint_frames
        c = build_condition(keypose_3d, keypose_at, trajectories_3d, n_frames=N)
        sk = build_sketch(keypose_2d, keypose_at, trajectories_2d, camera, n_frames=N)
        both = [n for i, n in enumerate(TRAJECTORY_JOINT_NAMES)
                if c["traj_mask"][:, i].any() and sk["traj_mask"][:, i].any()]
        if both or (c["has_keypose"] and sk["has_keypose"]):
            raise ValueError(f"give each condition in 3D or in 2D, not both: "
                             f"{'keypose' if not both else ', '.join(both)} has both")
        drawn = sk["has_keypose"] or sk["has_trajectory"]
        if not isinstance(sketch_encoders, (bool, np.bool_)):
            raise TypeError(f"sketch_encoders must be True or False, got {sketch_encoders!r}")
        encoded = drawn and self.has_sketch_encoders and bool(sketch_encoders)
        if drawn and not encoded and not (guidance_final > 0 or inference_guidance > 0):
            raise ValueError(f"{self.path} has no 2D encoders (Sec. 5; `python -m "
                             f"physlab.motion.train --stage align`), so keypose_2d / "
                             f"trajectories_2d act through the inference guidance only: keep "
                             f"guidance_final > 0 or inference_guidance > 0")
        controlled = c["has_keypose"] or c["has_trajectory"]
        K = self.config.smooth_basis
        if frequencies is None:
            frequencies = min(CONTROL_FREQUENCIES if controlled else TEXT_FREQUENCIES, K) or None
        elif (isinstance(frequencies, bool) or not isinstance(frequencies, (int, np.integer))
              or not 1 <= frequencies <= K):
            raise ValueError(f"frequencies must be None or an integer in 1..{K} (the DCT "
                             f"frequencies this checkpoint's x̂₀ can keep), got {frequencies!r}"
                             if K else f"frequencies must be None: {self.path} has no "
                             f"low-pass output basis (smooth_basis = 0), got {frequencies!r}")
        absolute = K and self.config.representation == "absolute"
        smooth_text = absolute and not (controlled or drawn) and frequencies is not None
        path_frequencies, body_frequencies = (
            self._column_frequencies(name, value, default if smooth_text else None, absolute,
                                     frequencies or K)
            for name, value, default in (("path_frequencies", path_frequencies, PATH_FREQUENCIES),
                                         ("body_frequencies", body_frequencies, BODY_FREQUENCIES)))
        if controlled and not self.has_control:
            raise ValueError(f"{self.path} is a '{self.stage}' (text-only) checkpoint: it "
                             f"cannot take keypose_3d / trajectories_3d. Train the control "
                             f"stage on it: `python -m physlab.motion.train --stage control "
                             f"--base-ckpt {self.path} --out runs/control.pt`, or leave out "
                             f"the keypose and trajectories")

        a = torch.tensor(self.text_cache.get(action), dtype=torch.float32)[None]   # (1, 384)
        cond = None                 # the 3D conditions (the network's, and the guidance's)
        if controlled or encoded:
            cond = {"trajectory": torch.tensor(c["trajectory"], dtype=torch.float32)[None],
                    "traj_mask": torch.tensor(c["traj_mask"])[None],
                    "keypose": torch.tensor(c["keypose"], dtype=torch.float32)[None],
                    "key_frame": torch.tensor([c["key_frame"]], dtype=torch.int64),
                    "keypose_mask": torch.tensor([c["has_keypose"]])}
        net_cond = cond
        if encoded:                 # the drawing through E^2D_tr / E^2D_k (Sec. 5)
            net_cond = self._sketch_condition(cond, c, sk, camera)
            if not controlled:
                cond = None
        if net_cond is not None and not self.model.single_controlnet:
            # The condition encoders see only the conditions, which no step changes: encode
            # them once per clip, not at each of the `steps` network calls (same numbers).
            with torch.no_grad():
                net_cond = dict(net_cond, embeddings=self.model.condition_embeddings(net_cond))
        target = None
        if cond is not None and (inference_guidance > 0 or guidance_final > 0):
            # the loss functions read targets from (1, N, 22, 3) joints: write the keypose
            # into its frame and the trajectory points into theirs (only these are read)
            tr = np.zeros((N, len(JOINT_NAMES), 3))
            tr[:, list(TRAJECTORY_JOINTS)] = c["trajectory"]                 # zeros if masked
            key = np.zeros((N, len(JOINT_NAMES), 3))
            key[c["key_frame"]] = c["keypose"]
            target = tuple(torch.tensor(v, dtype=torch.float32)[None] for v in (tr, key))
        sketch = None
        if drawn:
            sketch = {"projection": torch.tensor(sk["projection"], dtype=torch.float32),
                      "trajectory": torch.tensor(sk["trajectory"], dtype=torch.float32)[None],
                      "traj_mask": torch.tensor(sk["traj_mask"])[None],
                      "keypose": None if sk["keypose"] is None else
                      torch.tensor(sk["keypose"], dtype=torch.float32)[None],
                      "key_frame": sk["key_frame"]}
        guided = target is not None or sketch is not None

        # The sampling loop, written out (as diffusers pipelines do): start from noise x_T,
        # then at every timestep ask the network for its output (with classifier-free
        # guidance, Eq. (14)), optionally correct it by the inference guidance (supp. C),
        # and let the scheduler take one DDIM / DDPM step to the next, less noisy level.
        sched = self.scheduler
        full = method == "ddpm" and int(steps) == sched.num_train_timesteps
        timesteps = sched.set_timesteps(int(steps), spacing="trailing" if full else None)
        g = torch.Generator().manual_seed(int(seed))
        shape = (1, self.config.n_frames, self.config.feature_dim)           # (1, T, D)
        x = torch.randn(shape, generator=g)                                  # x_T ~ N(0, I)
        w_c = float(condition_scale)
        bar = _progress(self._pairs(timesteps), progress, f"{method} sampling")
        text_only = not (controlled or drawn)                      # the text model's requests
        with torch.no_grad(), self._using_text_model(text_only), \
                self._frequencies(frequencies, path_frequencies, body_frequencies):
            for t, t_prev in bar:
                t_in = torch.tensor([t])
                w = guidance_at(guidance_scale, t, sched.num_train_timesteps)
                final = t_prev == -1
                iters = guidance_final if final else inference_guidance
                if guided and iters > 0 and not final and guidance_space == "network":
                    x, out = self._guide_network(x, t_in, a, cond, w, target, iters,
                                                 guidance_optimizer, w_c, sketch,
                                                 net_cond)                  # Eq. (15)
                else:
                    out = self._predict(x, t_in, a, net_cond, w, w_c)       # x̂₀ / ε̂ / v̂
                    if guided and iters > 0:
                        out = self._guide(out, x, t_in, cond, target, iters,
                                          float(guidance_proximity),
                                          "lbfgs" if final else guidance_optimizer, sketch)
                if method == "ddim":
                    x, x0 = sched.ddim_step(out, t, t_prev, x)
                else:
                    x, x0 = sched.ddpm_step(out, t, x, generator=g, t_prev=t_prev)
        # The result is the clean estimate x̂₀ of the last step, not the sampler's x at the
        # first training level (ᾱ_0 < 1 in MLD's schedule): that x keeps ~70 % of the last
        # step's residual x_t − √ᾱ_t x̂₀ and so undoes most of a last-step guidance.
        with self._using_text_model(text_only):            # its statistics decode its x̂₀
            feats, joints = self._decode(x0)                        # (T, D), (N, 22, 3)
        if body_constraints and np.all(np.isfinite(joints)):
            lengths = clip_bone_lengths(c["keypose"][None]) if c["has_keypose"] else None
            toes = [TRAJECTORY_JOINTS.index(j) for j in FOOT_TOES]
            met = guided and (inference_guidance > 0 or guidance_final > 0)  # toes on strokes
            pinned = (c["traj_mask"][:, toes] | sk["traj_mask"][:, toes] if met
                      else np.zeros((N, len(toes)), dtype=bool))
            if c["has_keypose"] or sk["has_keypose"]:
                pinned[c["key_frame"]] = True
            joints = constrain_body(joints, lengths, lock=bool(foot_lock), pinned=pinned)
        if not np.all(np.isfinite(joints)):
            raise FloatingPointError(f"sampling with {self.path} produced NaN/inf joints; "
                                     f"the checkpoint may be diverged")
        return (joints, feats) if return_features else joints

    def denoise_from(self, joints, level, action, noise_seed=0, steps=None,
                     guidance_scale=TEXT_GUIDANCE, frequencies=None):
        """A real clip noised to ``level`` and denoised back, text only: how much of its
        detail the network keeps (the diagnostic of :func:`~physlab.motion.evaluate.detail_kept`).

        ``joints`` (N, 22, 3) canonical clip; ``level`` an int in [0, T) — the clip's features
        are noised to it by the forward process, q(x_t | x₀) — or None: start from pure noise
        as :meth:`__call__` does (the clip is then ignored); a DDIM step from ``level`` and
        the steps of a ``steps``-step schedule below it then run with text guidance ``guidance_scale`` for
        ``action``, keeping ``frequencies`` DCT frequencies (default: the text-only
        default). No path low-pass, no body constraints: the network's own result — the
        frozen base of a control model (:attr:`denoiser`), not its :attr:`text_model`.
        Returns the (N, 22, 3) joints decoded from the last x̂₀."""
        J = np.asarray(joints, dtype=float)
        N = self.config.n_joint_frames
        if J.shape != (N, 22, 3) or not np.all(np.isfinite(J)):
            raise ValueError(f"joints must be a finite ({N}, 22, 3) array, got shape {J.shape}")
        T = self.scheduler.num_train_timesteps
        if level is not None and (isinstance(level, bool)
                                  or not isinstance(level, (int, np.integer))
                                  or not 0 <= level < T):
            raise ValueError(f"level must be None (pure noise) or an integer in [0, {T}), got "
                             f"{level!r}")
        timesteps = self.scheduler.set_timesteps(int(steps or DEFAULT_STEPS))
        x0 = torch.tensor(self.stats.normalize(encode_motion(J, self.config.representation,
                                                             fps=20)),
                          dtype=torch.float32)[None]                        # (1, T, D)
        noise = torch.randn(x0.shape, generator=torch.Generator().manual_seed(int(noise_seed)))
        if level is None:
            x = noise
        else:
            x = self.scheduler.add_noise(x0, noise, torch.tensor([int(level)]))
            timesteps = torch.cat([torch.tensor([int(level)]),
                                   timesteps[timesteps < int(level)]])       # start at level
        a = torch.tensor(self.text_cache.get(action), dtype=torch.float32)[None]
        K = self.config.smooth_basis
        k = min(TEXT_FREQUENCIES, K) if frequencies is None and K else frequencies
        with torch.no_grad(), self._frequencies(k):
            for t, t_prev in self._pairs(timesteps):
                out = self._predict(x, torch.tensor([t]), a, None, float(guidance_scale))
                x, x0_hat = self.scheduler.ddim_step(out, t, t_prev, x)
        return self._decode(x0_hat)[1]


# ----------------------------------------------------------------------------- generate()


@functools.lru_cache(maxsize=2)
def _cached_generator(path, mtime_ns, size):
    return Generator.from_checkpoint(path)


def load_generator(checkpoint=None):
    """:meth:`Generator.from_checkpoint`, cached per file (reloaded if the file changes);
    ``checkpoint`` None -> :data:`DEFAULT_CHECKPOINT`."""
    path = Path(checkpoint if checkpoint is not None else DEFAULT_CHECKPOINT).resolve()
    if not path.is_file():
        raise FileNotFoundError(f"no motion checkpoint at {path}; make one with "
                                f"{_train_commands(path)}")
    st = path.stat()
    return _cached_generator(str(path), st.st_mtime_ns, st.st_size)


def generate(action, keypose_3d=None, keypose_at="first", trajectories_3d=None,
             keypose_2d=None, trajectories_2d=None, camera=None, seed=0, guidance_scale=None,
             steps=None, checkpoint=None, **options):
    """``(40, 22, 3)`` joints (m) for an action text and optional keypose / trajectories, in
    3D or drawn in 2D in the view of ``camera`` (DESIGN.md's ``from physlab.motion import
    generate``); ``checkpoint`` defaults to :data:`DEFAULT_CHECKPOINT`, loaded once and
    cached. ``options``: the other keywords of :meth:`Generator.__call__`."""
    gen = load_generator(checkpoint)
    return gen(action, keypose_3d=keypose_3d, keypose_at=keypose_at,
               trajectories_3d=trajectories_3d, keypose_2d=keypose_2d,
               trajectories_2d=trajectories_2d, camera=camera, seed=seed,
               guidance_scale=guidance_scale, steps=steps, **options)
