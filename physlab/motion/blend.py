"""Blending adjacent motion clips into one animation (Sketch2Anim Sec. 6 "Motion Blending",
supp. D, Eqs. (17)–(18), Table A4).

A storyboard gives one 40-frame clip per sketch frame. Played back to back they pop: the
next clip starts wherever and however it was generated. Two steps join them:

1. **Placement.** :func:`place_after` rotates the next clip about the vertical and moves it
   on the floor so that it starts facing where the previous clip ended facing, and where
   the previous clip's pelvis would be after the transition at the two clips' mean speed.
2. **Transition.** ``l`` new frames go between the clips (:func:`blend`). The baselines fill
   them without a model: linear interpolation of joint positions, slerp or SQUAD of the joint
   rotations (:mod:`physlab.motion.transitions`). Sketch2Anim's method (``"inversion"``)
   takes a window of the model's length (40 frames: the last ``c_a`` frames of the first
   clip, the ``l`` linearly blended frames, the first ``c_b`` frames of the second clip),
   inverts it to noise by deterministic DDIM inversion (Eq. (17)), and denoises it again
   with the text of both actions under classifier-free guidance while an L-BFGS guidance
   keeps the window's context frames on the two clips' global joints (Eq. (18))::

       G_m = ‖R(slice(x̂₀^Inv, p)) − R(x̂₀^p)‖² + ‖R(slice(x̂₀^Inv, q)) − R(x̂₀^q)‖²

   so the model re-plans the gap as a motion it knows while both neighbours stay put.
   ``"inpaint"`` is a DoubleTake-like baseline (Shafir et al. 2023, a second take over the
   transition): the same window denoised from fresh noise (seeded) with the context rows
   replaced at every step by the clips' frames noised to that level (MDM-style inpainting),
   no G_m guidance. In both, the
   final x̂₀ is the window; its context frames are cross-faded into the clips (they differ
   from them by the guidance's residual only), so nothing jumps where the window ends.

Differences from the paper, all measured in lesson 11 / ``python -m physlab.motion.evaluate
--blending``: physlab's model has a fixed 40-frame window, so the blending window is 40
frames centred on the gap (the paper's MLD latent takes longer motions); by default the
guidance works on x̂₀ of each step (:meth:`~physlab.motion.sampling.Generator._guide`, no
backpropagation through the network; ``guidance_space="network"`` is the paper's z_t form,
3.5x slower, as smooth); the combined action ``a_{p+q}`` is the mean of the two action
embeddings (no new text to encode); and the guidance also pulls the gap towards its linear
initialisation (:data:`INIT_WEIGHT`), because the shipped model does not reconstruct what it
inverts (invert + denoise without guidance: 0.34–0.44 m from the input with the 5000-step
base; part of that is the schedule, whose first levels are nearly noise-free so an
x̂₀-network's ε̂ amplifies its error ~24x: an *exact* Gaussian x̂₀-model round-trips only to
0.63 with these settings).
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np

from .features import _rotate_y, canonicalize, root_heading
from .skeleton import JOINT_NAMES

__all__ = ["BLEND_METHODS", "TRANSITION", "BlendResult", "place_after", "blend",
           "junction_step_ratio", "junction_acceleration_ratio", "BLEND_STEPS",
           "BLEND_GUIDANCE"]

#: Transition methods of :func:`blend`: naive concatenation (no gap), the model-free
#: baselines, and Sketch2Anim's inversion-based blending.
BLEND_METHODS = ("concat", "linear", "slerp", "squad", "inpaint", "inversion")
#: DDIM steps of the ``"inpaint"`` baseline (it starts from noise, as a generation does; 50 as
#: in the README's generation tables, generation's default is 25, ``sampling.DEFAULT_STEPS``).
INPAINT_STEPS = 50
#: Default transition length in frames (Sketch2Anim supp. D masks 20 frames = 1 s).
TRANSITION = 20
#: DDIM steps of the inversion and of the denoising that follows (fewer than generation's
#: 25: the window starts from a motion, not from noise).
BLEND_STEPS = 20
#: L-BFGS iterations of the G_m guidance at every denoising step and at the last one.
BLEND_GUIDANCE = (4, 20)
#: Fixed-point refinements per inversion step (:meth:`~physlab.motion.diffusion.
#: NoiseScheduler.invert`).
INVERSION_FIXED_POINT = 0
#: Weight of the pull of the transition frames towards their linear-blend initialisation in
#: the guidance (0 = the paper's G_m alone). Measured on 16 held-out phase-change windows
#: (``python -m physlab.motion.evaluate --blending``): the shipped model does not reconstruct
#: what it inverts (invert + denoise, no guidance: 0.34-0.44 m from the input), so with G_m
#: alone the gap becomes a detour (MPJPE to the real frames 0.41 m, linear blend 0.14 m);
#: weights 0.3 / 1 / 3: MPJPE 0.143 / 0.141 / 0.139 m, AUJ 0.35 / 0.29 / 0.24.
INIT_WEIGHT = 1.0
#: Frames over which a clip's velocity is averaged for :func:`place_after`.
_SPEED_FRAMES = 5


def _check_clip(x, name, min_frames=1):
    x = np.asarray(x, dtype=float)
    if x.ndim != 3 or x.shape[1:] != (len(JOINT_NAMES), 3):
        raise ValueError(f"{name} must be a (T, {len(JOINT_NAMES)}, 3) joints array (m), got "
                         f"shape {x.shape}")
    if len(x) < min_frames:
        raise ValueError(f"{name} needs at least {min_frames} frames, got {len(x)}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains NaN or inf")
    return x


def _check_transition(transition, upper=None):
    if isinstance(transition, bool) or not isinstance(transition, (int, np.integer)) \
            or transition < 0 or (upper is not None and transition > upper):
        rng = f"0..{upper}" if upper is not None else ">= 0"
        raise ValueError(f"transition must be an integer number of frames in {rng}, got "
                         f"{transition!r}")
    return int(transition)


def _check_gap(transition, method, upper=None):
    """The transition length of a method that fills a gap (not ``"concat"``): an integer in
    ``1..upper``; ValueError naming it otherwise."""
    l = _check_transition(transition, upper)
    if l < 1:
        raise ValueError(f"transition must be >= 1 frame for method {method!r} (use "
                         f"method='concat' for none), got {l}")
    return l


def place_after(prev, nxt, transition=TRANSITION, return_transform=False):
    """Move ``nxt`` so that it continues ``prev`` after a gap of ``transition`` frames.

    Rotation about the vertical through ``nxt``'s first pelvis by ``θ_prev − θ_next``
    (:func:`~physlab.motion.features.root_heading` of ``prev``'s last and ``nxt``'s first
    frame), then a horizontal shift putting ``nxt``'s first pelvis at ``prev``'s last pelvis
    plus ``(transition + 1)`` times the mean horizontal pelvis velocity of the two clips
    (each over its :data:`_SPEED_FRAMES` frames next to the gap). Heights are kept.

    prev : (Ta, 22, 3), nxt : (Tb, 22, 3) joints (m); transition : int >= 0 frames.
    Returns (Tb, 22, 3), ``nxt`` placed; with ``return_transform`` also ``(theta, offset)``
    ((float rad, (3,) m) with ``placed = R_y(theta) nxt + offset``).
    """
    a = _check_clip(prev, "prev")
    b = _check_clip(nxt, "nxt")
    l = _check_transition(transition)
    turn = float(root_heading(a[-1:])[0] - root_heading(b[:1])[0])
    pivot = np.array([b[0, 0, 0], 0.0, b[0, 0, 2]])
    b = _rotate_y(b - pivot, np.full(len(b), turn)) + pivot
    k = _SPEED_FRAMES
    va = np.diff(a[-k - 1:, 0], axis=0).mean(0) if len(a) > 1 else np.zeros(3)
    vb = np.diff(b[:k + 1, 0], axis=0).mean(0) if len(b) > 1 else np.zeros(3)
    target = a[-1, 0] + (l + 1) * (va + vb) / 2
    shift = np.array([target[0] - b[0, 0, 0], 0.0, target[2] - b[0, 0, 2]])
    if return_transform:      # R (x - pivot) + pivot + shift = R x + (pivot - R pivot + shift)
        offset = pivot - _rotate_y(pivot[None, None], np.array([turn]))[0, 0] + shift
        return b + shift, turn, offset
    return b + shift


@dataclass
class BlendResult:
    """Two clips joined by a transition (:func:`blend`).

    joints : (Ta + l + Tb, 22, 3) m, the whole motion; ``transition`` : slice of the ``l``
    new frames in ``joints``; ``window`` : slice of the frames the method changed (the
    transition plus, for ``"inversion"``, the context frames it cross-fades); ``method``;
    ``seconds`` : wall time of the transition.
    """
    joints: np.ndarray
    transition: slice
    window: slice
    method: str
    seconds: float = 0.0


def _smoothstep(n):
    """n weights rising smoothly from ~0 to ~1 (exclusive): 3s² − 2s³ at s = k/(n+1)."""
    s = np.arange(1, n + 1) / (n + 1)
    return 3 * s ** 2 - 2 * s ** 3


def blend(clip_a, clip_b, transition=TRANSITION, method="inversion", actions=None,
          generator=None, seed=0, steps=BLEND_STEPS, guidance=BLEND_GUIDANCE,
          guidance_scale=None, body_constraints=True, progress=False,
          fixed_point=INVERSION_FIXED_POINT, init_weight=INIT_WEIGHT, guidance_space="x0"):
    """Join ``clip_a`` and ``clip_b`` (already placed, :func:`place_after`) by ``transition``
    new frames (module docstring).

    Parameters
    ----------
    clip_a, clip_b : (Ta, 22, 3), (Tb, 22, 3) joints (m), world frame, y up.
    transition : int, frames between them (``"concat"``: ignored, 0).
    method : one of :data:`BLEND_METHODS`.
    actions : ``(text_a, text_b)`` action texts, needed by ``"inversion"`` / ``"inpaint"``.
    generator : a :class:`~physlab.motion.sampling.Generator` (default: the shipped one),
        for the two model-based methods; seed : int, the starting noise of ``"inpaint"``
        (``"inversion"`` is deterministic and ignores it); steps : DDIM steps of inversion
        and denoising (``"inpaint"``: at least :data:`INPAINT_STEPS`).
    guidance : ``(per_step, final)`` L-BFGS iterations of the G_m guidance, Eq. (18).
    guidance_scale : classifier-free guidance w on the combined text (None: the generator's
        text-only default).
    body_constraints : rigid bones and feet on the floor for the new window
        (:func:`~physlab.motion.body.constrain_body`).
    fixed_point : int >= 0, fixed-point refinements per inversion step (0: plain DDIM
        inversion, the default; with the shipped x̂₀-model and schedule more refinements
        make the round trip worse, see :meth:`~physlab.motion.diffusion.NoiseScheduler.invert`).
    init_weight : pull of the gap towards its linear initialisation in the guidance.
    guidance_space : ``"x0"`` (optimise each step's x̂₀, no backpropagation through the
        network: cheap) or ``"network"`` (Eq. (18)'s form: optimise ``z_t`` through the
        network, :meth:`~physlab.motion.sampling.Generator._guide_network`) for the per-step
        guidance; the final step's guidance is on x̂₀ either way.
    progress : tqdm bars of the inversion and the denoising.

    Returns
    -------
    :class:`BlendResult`.
    """
    import time

    if method not in BLEND_METHODS:
        raise ValueError(f"method must be one of {BLEND_METHODS}, got {method!r}")
    a = _check_clip(clip_a, "clip_a", 2)
    b = _check_clip(clip_b, "clip_b", 2)
    t0 = time.perf_counter()
    if method == "concat":
        j = np.concatenate([a, b])
        return BlendResult(j, slice(len(a), len(a)), slice(len(a), len(a)), method,
                           time.perf_counter() - t0)
    l = _check_gap(transition, method)
    if method in ("linear", "slerp", "squad"):
        from . import transitions
        fill = getattr(transitions, f"{method}_transition")(a, b, l)
        j = np.concatenate([a, fill, b])
        s = slice(len(a), len(a) + l)
        return BlendResult(j, s, s, method, time.perf_counter() - t0)
    if guidance_space not in ("x0", "network"):
        raise ValueError(f"guidance_space must be 'x0' or 'network', got {guidance_space!r}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    if method == "inpaint":                 # the baseline keeps the context by inpainting
        guidance, init_weight, steps = (0, 0), 0.0, max(int(steps), INPAINT_STEPS)
    j, window = _inversion_blend(a, b, l, actions, generator, seed, steps, guidance,
                                 guidance_scale, body_constraints, progress, fixed_point,
                                 init_weight, guidance_space, inpaint=method == "inpaint")
    return BlendResult(j, slice(len(a), len(a) + l), window, method, time.perf_counter() - t0)


@contextlib.contextmanager
def _restored(sched, previous):
    """Put the scheduler's sampling timesteps back as they were (``previous``) on leaving."""
    try:
        yield
    finally:
        sched.timesteps, sched.num_inference_steps = previous


def _check_guidance(guidance):
    try:
        per_step, final = (int(v) for v in guidance)
    except (TypeError, ValueError):
        raise ValueError(f"guidance must be a pair (per_step, final) of L-BFGS iteration "
                         f"counts, got {guidance!r}") from None
    if per_step < 0 or final < 0:
        raise ValueError(f"guidance counts must be >= 0, got {guidance!r}")
    return per_step, final


def _inversion_blend(a, b, l, actions, generator, seed, steps, guidance, guidance_scale,
                     body_constraints, progress, fixed_point, init_weight, space, inpaint=False):
    """Sketch2Anim supp. D on a window of the model's length; returns (joints, window)."""
    import math

    import torch

    from .body import clip_bone_lengths, constrain_body
    from .features import decode_motion, encode_motion
    from .sampling import TEXT_FREQUENCIES, TEXT_GUIDANCE, _progress, load_generator
    from .transitions import linear_transition

    if (not isinstance(actions, (tuple, list)) or len(actions) != 2
            or not all(isinstance(t, str) and t.strip() for t in actions)):
        raise ValueError(f"method 'inversion' needs actions=(text_a, text_b), the two clips' "
                         f"action texts, got {actions!r}")
    per_step, final = _check_guidance(guidance)
    if not (math.isfinite(init_weight) and init_weight >= 0):
        raise ValueError(f"init_weight must be a finite number >= 0, got {init_weight!r}")
    if isinstance(fixed_point, bool) or not isinstance(fixed_point, (int, np.integer)) \
            or fixed_point < 0:
        raise ValueError(f"fixed_point must be an integer >= 0, got {fixed_point!r}")
    if guidance_scale is not None and not (math.isfinite(guidance_scale)
                                           and guidance_scale >= 0):
        raise ValueError(f"guidance_scale must be None or a finite number >= 0, got "
                         f"{guidance_scale!r}")
    if not isinstance(body_constraints, (bool, np.bool_)):
        raise TypeError(f"body_constraints must be True or False, got {body_constraints!r}")
    gen = generator if generator is not None else load_generator()
    cfg = gen.config
    if inpaint and cfg.representation != "absolute":
        raise ValueError(f"method='inpaint' needs a checkpoint of 'absolute' features (one "
                         f"feature row per frame, to replace the context rows); {gen.path} "
                         f"has {cfg.representation!r} features: use method='inversion'")
    N = cfg.n_joint_frames
    if l > N - 2:
        raise ValueError(f"transition must be at most {N - 2} frames for 'inversion' (the "
                         f"model's window is {N} frames and keeps >= 1 context frame on each "
                         f"side), got {l}")
    ca = (N - l) // 2
    cb = N - l - ca
    if len(a) < ca or len(b) < cb:
        raise ValueError(f"clip_a needs >= {ca} and clip_b >= {cb} frames for a {l}-frame "
                         f"transition, got {len(a)} and {len(b)}")
    before, after = a[-ca:], b[:cb]
    init = np.concatenate([before, linear_transition(before, after, l), after])   # (N, 22, 3)
    wc, theta0, offset = canonicalize(init, ground=False, return_transform=True)
    feats = gen.stats.normalize(encode_motion(wc, cfg.representation))           # (n, D)
    x0 = torch.tensor(feats, dtype=torch.float32)[None]                           # (1, n, D)

    # a_{p+q}: the two action embeddings averaged (renormalised to their mean length)
    e = np.stack([gen.text_cache.get(t) for t in actions]).astype(np.float64)    # (2, 384)
    m = e.mean(0)
    m *= np.linalg.norm(e, axis=1).mean() / max(np.linalg.norm(m), 1e-12)
    text = torch.tensor(m, dtype=torch.float32)[None]                             # (1, 384)
    w = float(TEXT_GUIDANCE if guidance_scale is None else guidance_scale)
    keep = np.r_[0:ca, N - cb:N]                                                  # context
    target = torch.tensor(wc[keep], dtype=torch.float32)[None]                    # (1, k, 22, 3)

    gap = np.r_[ca:N - cb]
    init_gap = torch.tensor(wc[gap], dtype=torch.float32)[None]                   # (1, l, 22, 3)

    def g_m(joints):               # supp. Eq. (18)'s G_m (metres²) + physlab's pull to the init
        g = ((joints[:, keep] - target) ** 2).sum(-1).mean()
        if init_weight:                                # physlab: stay near the blend
            g = g + init_weight * ((joints[:, gap] - init_gap) ** 2).sum(-1).mean()
        return g

    sched = gen.scheduler
    drop = torch.tensor([False])
    freq = min(TEXT_FREQUENCIES, cfg.smooth_basis) or None
    previous = getattr(sched, "timesteps", None), getattr(sched, "num_inference_steps", None)
    with gen._frequencies(freq), _restored(sched, previous):
        if inpaint:        # DoubleTake-like: start from noise, keep the known frames noised
            g = torch.Generator().manual_seed(int(seed))
            x = torch.randn(x0.shape, generator=g)
            known_noise = torch.randn(x0.shape, generator=g)
        else:
            x = sched.invert(lambda x, t, c: gen.denoiser(x, t, text, drop), x0,
                             steps=int(steps), progress=progress,
                             fixed_point=fixed_point)                              # Eq. (17)
        timesteps = sched.set_timesteps(int(steps))
        with torch.no_grad():
            for i, t in enumerate(_progress(timesteps.tolist(), progress, "blend denoising")):
                t_prev = int(timesteps[i + 1]) if i + 1 < len(timesteps) else -1
                t_in = torch.tensor([t])
                if inpaint:        # the context rows: the clips' frames at this noise level
                    x[:, keep] = sched.add_noise(x0, known_noise, t)[:, keep]
                iters = final if t_prev == -1 else per_step
                if iters and space == "network" and t_prev != -1:                # Eq. (18)
                    x, out = gen._guide_network(x, t_in, text, None, w, None, iters,
                                                loss_fn=g_m)
                else:
                    out = gen._predict(x, t_in, text, None, w)                    # CFG
                    if iters:
                        out = gen._guide(out, x, t_in, None, None, iters, 0.0, "lbfgs",
                                         loss_fn=g_m)                             # Eq. (18)
                x, x0_hat = sched.ddim_step(out, t, t_prev, x)
    out = gen.stats.denormalize(x0_hat[0].double().numpy())
    win = decode_motion(out, cfg.representation)                                  # (N, 22, 3)
    win = _rotate_y(win, np.full(N, theta0)) + offset                             # world
    if not np.all(np.isfinite(win)):
        raise FloatingPointError("the blending window became NaN/inf; try fewer guidance "
                                 "iterations or another checkpoint")
    # cross-fade the context frames from the clips into the window and back; the body
    # constraints then use the clips' bone lengths, so where the window meets a clip with
    # those lengths nothing moves (animate_storyboard gives all its clips one skeleton)
    lengths = clip_bone_lengths(np.concatenate([before, after]))
    wa = _smoothstep(ca)[:, None, None]
    wb = _smoothstep(cb)[::-1, None, None]
    mixed_a = (1 - wa) * before + wa * win[:ca]
    mixed_b = (1 - wb) * after + wb * win[N - cb:]
    changed = np.concatenate([mixed_a, win[ca:N - cb], mixed_b])
    if body_constraints:      # rigid bones at the clips' lengths, feet not below the floor
        changed = constrain_body(changed, lengths, lock=False)
    j = np.concatenate([a[:-ca], changed, b[cb:]])
    return j, slice(len(a) - ca, len(a) + l + cb)


def _check_junction(joints, window, clips, margin):
    """``(x, start, stop)`` of a junction's arguments (:func:`junction_step_ratio`), with
    ``margin`` unchanged frames required on each side of ``window``."""
    x = _check_clip(joints, "joints", 2)
    if not isinstance(window, slice) or window.start is None or window.stop is None:
        raise ValueError(f"window must be a slice with a start and a stop (e.g. "
                         f"BlendResult.window), got {window!r}")
    if len(clips) != 2:
        raise ValueError(f"clips must be the two clips the junction joins, got {len(clips)}")
    start, stop = window.start, window.stop
    if not margin <= start <= stop <= len(x) - margin:
        side = "a frame" if margin == 1 else f"{margin} frames"
        raise ValueError(f"window must lie inside the motion with {side} on each side, got "
                         f"[{start}, {stop}) for {len(x)} frames")
    return x, start, stop


def junction_step_ratio(joints, window, clips, reference="median"):
    """How much a joined motion jumps at a junction: the largest frame-to-frame joint step
    into, inside and out of the changed frames ``window`` (a slice of ``joints``; an empty
    slice ``[k, k)`` for a plain cut before frame k) divided by a reference step of the two
    clips (each step: the largest joint displacement of a frame, m/frame):

    * ``"median"`` — the median step over both clips (the storyboard issue's bound is 1.5);
      a clip that barely moves (a bow) makes this small, and the walk it follows then
      "jumps" by its own stride: real phase changes score 13 on held-out mocap;
    * ``"local"`` — the largest step of each clip's second (20 frames) next to the
      junction: > 1 means the junction moves faster than either clip does there;
    * ``"straight"`` — the largest joint step of a straight, constant-speed join from the
      frame before the changed frames to the frame after them, the least any join of that
      length needs: when the clips barely move next to the junction but meet in different
      poses (a bow, then a wave that starts with the hand up), "local" counts the move the
      junction must make as a seam; a smooth ease-in-out scores π/2 ≈ 1.57 on "straight",
      a jump far more.

    joints : (T, 22, 3) the joined motion (m); window : slice (:attr:`BlendResult.window`);
    clips : the two (T_i, 22, 3) clips as they were before joining (the first ends at the
    junction, the second starts there). Returns float.
    """
    x, start, stop = _check_junction(joints, window, clips, 1)
    if reference not in ("median", "local", "straight"):
        raise ValueError(f"reference must be 'median', 'local' or 'straight', got "
                         f"{reference!r}")

    def steps(c, name):
        return np.linalg.norm(np.diff(_check_clip(c, name, 2), axis=0), axis=-1).max(axis=-1)

    step = np.linalg.norm(np.diff(x, axis=0), axis=-1).max(axis=-1)            # (T-1,)
    if reference == "median":
        ref = np.median(np.concatenate([steps(c, f"clips[{i}]") for i, c in enumerate(clips)]))
    elif reference == "local":
        ref = max(steps(np.asarray(clips[0])[-21:], "clips[0]").max(),
                  steps(np.asarray(clips[1])[:21], "clips[1]").max())
    elif stop == start:
        raise ValueError("reference='straight' needs changed frames: a plain cut's window is "
                         "empty (its straight join is the jump itself); use 'median' or "
                         "'local'")
    else:                          # frames start-1 and stop are unchanged: span them evenly
        ref = np.linalg.norm(x[stop] - x[start - 1], axis=-1).max() / (stop - start + 1)
    return float(step[start - 1:max(stop, start)].max() / max(ref, 1e-9))


def junction_acceleration_ratio(joints, window, clips):
    """Whether a junction shows as a seam: the largest joint acceleration
    ``‖x_{t+1} − 2 x_t + x_{t−1}‖`` (m/frame²) over the changed frames ``window`` and the two
    frames on each side of it, divided by the largest acceleration of the two clips within
    their second (20 frames) next to the junction. A seam is a change of velocity the clips
    do not make: a plain cut scores 4–110 on the example storyboard, a linear blend's kinks
    3.5–5 where a still bow meets a wave, the inversion blend 0.6–1.8 (seeds 0–3). Unlike
    :func:`junction_step_ratio`'s ``"local"`` reference, a fast but smooth move between two
    still clips in different poses is not counted.

    joints, window, clips : as :func:`junction_step_ratio` (a plain cut's empty window
    ``[k, k)`` measures the accelerations around frame k). Returns float.
    """
    x, start, stop = _check_junction(joints, window, clips, 2)

    def acc(c, name):
        c = _check_clip(c, name, 3)
        return np.linalg.norm(c[2:] - 2 * c[1:-1] + c[:-2], axis=-1).max(axis=-1)

    ref = max(acc(np.asarray(clips[0])[-21:], "clips[0]").max(),
              acc(np.asarray(clips[1])[:21], "clips[1]").max())
    return float(acc(x[start - 2:stop + 2], "joints").max() / max(ref, 1e-9))
