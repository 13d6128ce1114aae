"""Demos for lesson 09: a text- and sketch-conditioned motion diffusion model (Zhong et al.
2025, "Sketch2Anim: Towards Transferring Sketch Storyboards into 3D Animation", Secs. 3–4,
Eqs. (1)–(9) and (14); DDPM, Ho et al. 2020; DDIM, Song et al. 2021).

Every ``*_demo`` function is a widget callback (keyword parameters in, a
:class:`matplotlib.figure.Figure` out); the other functions compute the lesson's numbers
(``*_comparison``, ``*_sweep``, ``*_moments``, ...) or draw its static figures
(``*_figure``). The model, scheduler, metrics and 3-D views live in :mod:`physlab.motion`
and :mod:`physlab.viz.view3d`; this module only wires them together.

Conventions: joints are ``(T, 22, 3)`` float arrays in metres, y up, in the canonical window
frame (pelvis of frame 0 at ``x = z = 0`` facing ``+z``); a generated clip has ``T = 40``
frames (2 s at 20 fps); the shipped checkpoints denoise its 40 ``"absolute"`` feature rows of
``D = 70`` numbers (HumanML3D-style ``"relative"`` checkpoints: 39 rows of 137, the features
lesson 09 explains first; :data:`~physlab.motion.features.REPRESENTATIONS`). Features called
"normalised" are ``(f - mean) / std`` with the checkpoint's
:class:`~physlab.motion.features.FeatureStats`: the space the diffusion runs in.

Checkpoints: every function that samples takes ``checkpoint`` (a path; None =
:data:`~physlab.motion.sampling.DEFAULT_CHECKPOINT`) and loads it once per process through
:func:`~physlab.motion.sampling.load_generator`. Sampling runs on one torch thread
(:func:`one_thread`): for a batch of 2 rows the thread pool costs more than it gains.
"""
from __future__ import annotations

import contextlib
import functools
import time
import warnings
from pathlib import Path

import numpy as np

from physlab.motion import metrics as M
from physlab.motion.dataset import load_clips, make_windows
from physlab.motion.features import (
    CONTACTS,
    RIC,
    ROOT_ANG_VEL,
    ROOT_HEIGHT,
    ROOT_LIN_VEL,
    decode_motion,
    encode_motion,
    joints_to_features,
)
from physlab.motion.skeleton import JOINT_NAMES
from physlab.viz.plots import new_figure

__all__ = [
    "CONTROL_ROWS",
    "FIG_DPI",
    "FPS",
    "GUIDANCE_ACTIONS",
    "GUIDANCE_SCALES",
    "NOISE_LEVELS",
    "RARE_ACTIONS",
    "SAMPLERS",
    "UNSEEN_ACTIONS",
    "WALK_CLIP",
    "action_speeds",
    "condition_kwargs",
    "control_comparison",
    "control_figure",
    "decode",
    "embedding_figure",
    "embedding_neighbourhood",
    "export_bvh",
    "feature_channels",
    "generator",
    "guidance_by_level",
    "guidance_by_level_figure",
    "guidance_demo",
    "guidance_sweep",
    "guidance_sweep_figure",
    "motion_stats",
    "noised_features",
    "noising_figure",
    "noising_moments",
    "normalized_features",
    "one_thread",
    "real_speeds",
    "real_windows",
    "root_speed",
    "sampler_comparison",
    "sampler_figure",
    "schedule_figure",
    "strobe_image",
    "text_model_comparison",
    "text_model_figure",
    "walk_figure",
    "walk_window",
    "lesson_windows",
    "write_lesson_windows",
    "LESSON_WINDOWS",
]

#: Bandai-Namco contents whose normal-style take-001 windows ship in :data:`LESSON_WINDOWS`
#: (the guidance sweep's walk and run, the guidance-by-level figure's run and wave).
SHIPPED_CONTENTS = ("walk", "run", "wave-right-hand")
#: Actions of :func:`guidance_by_level`: text -> Bandai-Namco content. The run's speed must
#: come from the text; the wave must stay on the spot.
LEVEL_ACTIONS = {"a person runs": "run", "a person waves the right hand": "wave-right-hand"}
#: Frame rate of every clip here (Hz), HumanML3D's and Sketch2Anim's.
FPS = 20.0
#: Resolution of the lesson's figures (dots per inch); figures stay small.
FIG_DPI = 80
#: The Bandai-Namco walk of Secs. 2–3 ("a person walks", style normal, take 001).
WALK_CLIP = "dataset-1_walk_normal_001"
#: First frame of the walk window of Secs. 2–3.
LESSON_WALK_START = 20
#: Held-out windows of Sec. 6 (the control comparison).
LESSON_HELD_OUT = 6
#: The real windows the lesson uses, shipped so that it runs without ../shared/data
#: (derived from Bandai-Namco, CC BY-NC 4.0: data/motion/README.md); see :func:`lesson_windows`.
LESSON_WINDOWS = Path(__file__).resolve().parents[2] / "data" / "motion" / "lesson_windows.npz"
#: Noise levels t (0-based, of T = 1000) at which the walk is shown dissolving.
NOISE_LEVELS = (0, 100, 250, 500, 750, 999)
#: Samplers of Sec. 4: label -> (method, steps) of :meth:`Generator.__call__` (a full-length
#: DDPM run visits every timestep 999 .. 0).
SAMPLERS = {"DDPM, 1000 steps": ("ddpm", 1000), "DDIM, 50 steps": ("ddim", 50),
            "DDIM, 10 steps": ("ddim", 10)}
#: Action texts of the guidance widget: training texts first, then two texts no clip has.
UNSEEN_ACTIONS = ("a person jogs", "a person hops")
GUIDANCE_ACTIONS = ("a person walks", "a person runs", "a person walks backwards",
                    "a person kicks", "a person waves the right hand", "a person bows",
                    "a person dances") + UNSEEN_ACTIONS
#: Guidance scales w of the sweep of Sec. 5 (Sketch2Anim uses 7.5).
GUIDANCE_SCALES = (0.0, 1.0, 2.5, 5.0, 7.5, 10.0, 15.0)

_CAMERA = "iso"
_IMG = (360, 280)                       # strobe images (width, height) in pixels


# ---------------------------------------------------------------------------- helpers
@contextlib.contextmanager
def one_thread():
    """Run torch on one intra-op thread inside the block, restoring the setting after."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


@contextlib.contextmanager
def _quiet_encoder_loading(needed=True):
    """Hide transformers' "Loading weights" progress bar (in a notebook a tqdm widget that
    would be stored with the lesson) while the text encoder may load; restored after."""
    if not needed:
        yield
        return
    try:
        from transformers.utils import logging as hf_logging
    except ImportError:                          # no transformers: nothing to silence
        yield
        return
    was = hf_logging.is_progress_bar_enabled()
    hf_logging.disable_progress_bar()
    try:
        yield
    finally:
        if was:
            hf_logging.enable_progress_bar()


def _unknown(gen, texts):
    """True if some of ``texts`` are not in the checkpoint's embedding table (so sampling
    them loads the text encoder)."""
    return any(t not in gen.text_cache for t in texts)


def generator(checkpoint=None):
    """The :class:`~physlab.motion.sampling.Generator` of ``checkpoint`` (None =
    ``DEFAULT_CHECKPOINT``), loaded once per file and process."""
    from physlab.motion.sampling import load_generator

    return load_generator(checkpoint)


def _figure(ncols, width, height, width_ratios=None):
    """A one-row :class:`Figure` of ``ncols`` panels, ``width`` x ``height`` inches each on
    average, at :data:`FIG_DPI`; returns ``(fig, axes)`` (one Axes if ``ncols == 1``)."""
    if width_ratios is None:
        fig, axes = new_figure(ncols, 1, width=width, height=height)
    else:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(width * ncols, height), layout="constrained")
        axes = fig.subplots(1, ncols, width_ratios=width_ratios)
    fig.set_dpi(FIG_DPI)
    return fig, axes


def _check_scale(w):
    if isinstance(w, bool) or not isinstance(w, (int, float, np.number)):
        raise TypeError(f"guidance_scale must be a number >= 0 (Sketch2Anim: 7.5), got {w!r}")
    w = float(w)
    if not (np.isfinite(w) and w >= 0):
        raise ValueError(f"guidance_scale must be a finite number >= 0 (Sketch2Anim: 7.5), "
                         f"got {w}")
    return w


def _short(text):
    """``"a person waves the right hand"`` -> ``"waves the right hand"``."""
    return text.removeprefix("a person ")


def root_speed(joints, fps=FPS):
    """(T-1,) horizontal pelvis speed (m/s) of a clip ``(T, 22, 3)``."""
    x = np.asarray(joints, dtype=float)
    return np.linalg.norm(np.diff(x[:, 0, [0, 2]], axis=0), axis=-1) * fps


def _show(ax, img, title=None, fontsize=8):
    ax.imshow(img)
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=fontsize)


# ---------------------------------------------------------------------------- Sec. 2: data
def _bandai_dir(data_root, what):
    """``data_root`` or the external Bandai-Namco folder; FileNotFoundError saying that only the
    shipped windows (:data:`LESSON_WINDOWS`) work without it."""
    from physlab.motion.dataset import bandai_namco_dir

    try:
        return bandai_namco_dir(data_root)
    except FileNotFoundError as e:
        raise FileNotFoundError(f"{what} needs the Bandai-Namco clips ({e}); without "
                                f"../shared/data the lesson uses the windows shipped in "
                                f"{LESSON_WINDOWS.name} (the default arguments)") from None


@functools.lru_cache(maxsize=1)
def lesson_windows():
    """The real windows lesson 09 needs, shipped in :data:`LESSON_WINDOWS` so that the lesson
    runs without ``../shared/data`` (Bandai-Namco, CC BY-NC 4.0; see ``data/motion/README.md``).

    Returns
    -------
    dict: ``walk`` (40, 22, 3) the window of :data:`WALK_CLIP` at frame 20 and ``walk_text``;
    ``real_walk`` / ``real_run`` / ``real_wave-right-hand`` (n, 40, 22, 3) the stride-10
    windows of the normal-style take-001 walk, run and wave (:func:`real_windows`,
    :data:`SHIPPED_CONTENTS`); ``speed_walk`` / ``speed_run`` / ``speed_wave-right-hand`` ()
    the mean pelvis speed of all windows of every clip of the content (:func:`real_speeds`);
    ``held_out`` (6, 40, 22, 3) with
    ``held_out_text`` / ``held_out_clip_id`` (6,) str, the windows of
    :func:`physlab.motion.evaluate.held_out_windows` ``(6)``. Arrays are float64, metres,
    canonical window frame. Rebuild with :func:`write_lesson_windows`.
    """
    if not LESSON_WINDOWS.is_file():
        raise FileNotFoundError(f"{LESSON_WINDOWS} is missing; it ships with physlab (restore "
                                f"it with git, or rebuild it with `make lesson-data`)")
    with np.load(LESSON_WINDOWS, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def write_lesson_windows(path=None, data_root=None):
    """Cut the windows of :func:`lesson_windows` from the Bandai-Namco clips and write them
    (atomically, ``np.savez_compressed``, no pickles) to ``path`` (default
    :data:`LESSON_WINDOWS`). Returns the Path."""
    from physlab._io import atomic_write
    from physlab.motion.evaluate import held_out_windows

    root = _bandai_dir(data_root, "write_lesson_windows")
    walk, text = walk_window(WALK_CLIP, start=LESSON_WALK_START, data_root=root)
    real = real_windows({c: c for c in SHIPPED_CONTENTS}, data_root=root)
    held = held_out_windows(LESSON_HELD_OUT, data_root=root)
    speeds = real_speeds({c: c for c in SHIPPED_CONTENTS}, data_root=root)
    arrays = {"walk": walk, "walk_text": np.array(text),
              **{f"real_{c}": real[c] for c in SHIPPED_CONTENTS},
              **{f"speed_{c}": np.array(speeds[c]) for c in SHIPPED_CONTENTS},
              "held_out": held["joints"],
              "held_out_text": np.array(held["text"]),
              "held_out_clip_id": np.array(held["clip_id"])}
    return atomic_write(path or LESSON_WINDOWS,
                        lambda tmp: np.savez_compressed(tmp, **arrays), suffix=".npz")


def walk_window(clip_id=WALK_CLIP, start=LESSON_WALK_START, data_root=None):
    """One real 40-frame window, canonicalised as in training
    (:func:`~physlab.motion.dataset.make_windows`).

    Parameters
    ----------
    clip_id : a Bandai-Namco clip id (BVH stem).
    start : int >= 0, first frame of the window in the clip (20 fps).
    data_root : None or the Bandai-Namco folder. With None, the default window comes from
        :func:`lesson_windows` (no external data needed); other windows read the clips.

    Returns
    -------
    (joints (40, 22, 3) float array in metres, text str).
    """
    bad = isinstance(start, bool) or not np.isfinite(start) or not float(start).is_integer()
    if bad or start < 0:
        raise ValueError(f"start must be an integer frame >= 0 (the first frame of the "
                         f"40-frame window), got {start!r}")
    if data_root is None and clip_id == WALK_CLIP and start == LESSON_WALK_START:
        w = lesson_windows()
        return w["walk"].copy(), str(w["walk_text"])
    clips = load_clips(_bandai_dir(data_root, f"walk_window({clip_id!r}, start={start!r})"),
                       clip_ids=[clip_id])
    n = clips[0].n_frames
    if not start <= n - 40:
        raise ValueError(f"start must be an integer frame in 0..{n - 40} (clip {clip_id} has "
                         f"{n} frames, a window 40), got {start!r}")
    w = make_windows(clips, length=40, stride=1)
    i = int(np.flatnonzero(w.start == int(start))[0])
    return w.joints[i], w.text[i]


def real_windows(actions, style="normal", take="001", data_root=None):
    """Real 40-frame windows (stride 10) of the clips behind some training texts.

    Parameters
    ----------
    actions : dict text -> Bandai-Namco content label, e.g. ``{"a person walks": "walk"}``.
    style, take : str, which clips of each content (default: the normal-style training take).
    data_root : None or the Bandai-Namco folder. With None, the normal-style take-001 walk,
        run and wave (:data:`SHIPPED_CONTENTS`) come from :func:`lesson_windows`; anything
        else reads the clips.

    Returns
    -------
    dict text -> (n, 40, 22, 3) float array (m), canonical windows.
    """
    from physlab.motion.dataset import read_labels

    if data_root is None and style == "normal" and take == "001" \
            and set(actions.values()) <= set(SHIPPED_CONTENTS):
        w = lesson_windows()
        return {text: w[f"real_{content}"].copy() for text, content in actions.items()}
    root = _bandai_dir(data_root, f"real_windows({sorted(set(actions.values()))}, "
                                  f"style={style!r}, take={take!r})")
    rows = read_labels(root)
    out = {}
    for text, content in actions.items():
        ids = [r["file"].rsplit("/", 1)[-1][:-4] for r in rows if r["content"] == content
               and r["style"] == style and r["take"] == take]
        if not ids:
            raise ValueError(f"no Bandai-Namco clip has content {content!r}, style {style!r}, "
                             f"take {take!r}")
        out[text] = make_windows(load_clips(root, clip_ids=ids)).joints
    return out


def real_speeds(actions, data_root=None):
    """Mean horizontal pelvis speed (m/s) over the stride-10 windows of *every* clip (all
    styles, both takes) of each content: what the text-adherence check
    (:func:`physlab.motion.evaluate.text_adherence`) calls the real speed of an action.

    ``actions`` dict text -> Bandai-Namco content; with ``data_root`` None the contents of
    :data:`SHIPPED_CONTENTS` come from :func:`lesson_windows`, anything else reads the clips.
    Returns dict text -> float."""
    from physlab.motion.evaluate import motion_statistics

    if data_root is None and set(actions.values()) <= set(SHIPPED_CONTENTS):
        w = lesson_windows()
        return {text: float(w[f"speed_{content}"]) for text, content in actions.items()}
    root = _bandai_dir(data_root, f"real_speeds({sorted(set(actions.values()))})")
    out = {}
    for text, content in actions.items():
        clips = load_clips(root, contents=[content], progress=False)
        if not clips:
            raise ValueError(f"no Bandai-Namco clip has content {content!r}")
        out[text] = float(motion_statistics(make_windows(clips).joints)[:, 2].mean())
    return out


def strobe_image(joints, every=5, size=_IMG, camera=_CAMERA, backend="auto", **kwargs):
    """A stroboscopic picture of a clip (:func:`physlab.viz.view3d.strobe`: capsule human,
    light = early, dark = late, keypose red, trajectories green): (H, W, 3) uint8."""
    from physlab.viz.view3d import strobe

    return strobe(joints, every=every, size=size, camera=camera, backend=backend, **kwargs)


def feature_channels(joints, fps=FPS):
    """A few HumanML3D-style feature channels of a clip, in physical units.

    Parameters
    ----------
    joints : (T, 22, 3) float array (m).

    Returns
    -------
    dict name -> (T-1,) float array: ``"forward speed (m/s)"`` (root_lin_vel z times fps, in
    the body's heading frame), ``"turning rate (°/s)"`` (root_ang_vel), ``"pelvis height (m)"``
    (root_height), ``"left toe height (m)"`` / ``"right toe height (m)"`` (ric y of joints 10,
    11), ``"left toe contact"`` (contacts column 1).
    """
    f = joints_to_features(joints, fps=fps)                                  # (T-1, 137)
    ric = f[:, RIC].reshape(len(f), 21, 3)                                   # joints 1..21
    return {
        "forward speed (m/s)": f[:, ROOT_LIN_VEL][:, 1] * fps,
        "turning rate (°/s)": np.degrees(f[:, ROOT_ANG_VEL][:, 0]) * fps,
        "pelvis height (m)": f[:, ROOT_HEIGHT][:, 0],
        "left toe height (m)": ric[:, 10 - 1, 1],
        "right toe height (m)": ric[:, 11 - 1, 1],
        "left toe contact": f[:, CONTACTS][:, 1],
    }


def walk_figure(joints, text="", backend="auto"):
    """Left: a strobe of the clip; right: some of its feature channels over time."""
    fig, (ax, ax2) = _figure(2, 4.5, 3.2, width_ratios=(1.0, 1.1))
    _show(ax, strobe_image(joints, backend=backend), f"“{text}” (real, 40 frames = 2 s)"
          if text else "real clip")
    ch = feature_channels(joints)
    t = np.arange(len(next(iter(ch.values())))) / FPS
    for name, c in (("forward speed (m/s)", "tab:blue"), ("pelvis height (m)", "tab:purple"),
                    ("left toe height (m)", "tab:green"), ("right toe height (m)", "tab:olive")):
        ax2.plot(t, ch[name], color=c, lw=1.5, label=name)
    contact = ch["left toe contact"] > 0.5
    ax2.fill_between(t, 0, 1, where=contact, step="post", color="tab:green", alpha=0.12,
                     transform=ax2.get_xaxis_transform(), lw=0, label="left toe contact = 1")
    ax2.set_xlabel("time (s)")
    ax2.set_title("feature channels of the rows (of 137 per row)", fontsize=8)
    ax2.legend(fontsize=6.5, loc="upper right", ncols=2)
    ax2.set_ylim(-0.05, max(2.0, 1.3 * max(ch["forward speed (m/s)"].max(), 1.0)))
    ax2.grid(alpha=0.3)
    return fig


# ---------------------------------------------------------------------------- Sec. 3: noising
def normalized_features(joints, checkpoint=None):
    """``x_0``: the normalised features of a 40-frame clip in the space the checkpoint's
    diffusion runs in (``(f - mean) / std``, float64): (39, 137) for HumanML3D-style
    ``"relative"`` features, (40, 70) for ``"absolute"`` ones (the shipped checkpoints)."""
    g = generator(checkpoint)
    return g.stats.normalize(encode_motion(joints, g.config.representation, fps=FPS))


def decode(x, checkpoint=None):
    """Joints (40, 22, 3) (m) of normalised features ``x``: de-normalise, then the exact
    inverse (:func:`~physlab.motion.features.decode_motion`; the ``R(.)`` of Sketch2Anim
    Eqs. (6) and (8))."""
    g = generator(checkpoint)
    return decode_motion(g.stats.denormalize(np.asarray(x, float)), g.config.representation)


def noised_features(x0, scheduler, ts=NOISE_LEVELS, seed=0):
    """The forward process q(x_t | x_0) at several noise levels with *one* draw of ε
    (DDPM Eq. (4)): ``x_t = √ᾱ_t x_0 + √(1 − ᾱ_t) ε``.

    Parameters
    ----------
    x0 : (T, D) float array, a clean sample (normalised features).
    scheduler : :class:`~physlab.motion.diffusion.NoiseScheduler`.
    ts : K ints in ``0 .. T-1``.
    seed : int, seeds ε ~ N(0, I) (numpy ``default_rng``).

    Returns
    -------
    (K, T, D) float64 array of x_t (the same ε for every t, so the sample dissolves
    continuously).
    """
    import torch

    x0 = np.asarray(x0, dtype=float)
    ts = [int(t) for t in np.atleast_1d(ts)]
    eps = np.random.default_rng(seed).standard_normal(x0.shape)
    K = len(ts)
    xt = scheduler.add_noise(torch.as_tensor(x0).expand(K, *x0.shape),
                             torch.as_tensor(eps).expand(K, *x0.shape),
                             torch.as_tensor(ts, dtype=torch.int64))         # Eq. (4)
    return xt.numpy()


def noising_moments(x0, scheduler, ts=(50, 250, 500, 999), n=256, seed=0):
    """Monte-Carlo check of q(x_t | x_0) = N(√ᾱ_t x_0, (1 − ᾱ_t) I).

    For each t, ``n`` draws of x_t; the slope of their per-element mean against ``x0``
    (least squares through the origin) estimates √ᾱ_t and their pooled variance about that
    mean estimates 1 − ᾱ_t.

    Parameters
    ----------
    x0 : (T, D) float array; scheduler : NoiseScheduler; ts : ints; n : int >= 2 draws;
    seed : int (numpy ``default_rng``).

    Returns
    -------
    dict of (K,) float arrays: ``t``, ``sqrt_alpha_bar``, ``slope``, ``one_minus_alpha_bar``,
    ``variance``.
    """
    import torch

    x0 = np.asarray(x0, dtype=float)
    if int(n) < 2:
        raise ValueError(f"n must be >= 2 draws, got {n}")
    rng = np.random.default_rng(seed)
    out = {k: [] for k in ("t", "sqrt_alpha_bar", "slope", "one_minus_alpha_bar", "variance")}
    for t in ts:
        eps = rng.standard_normal((int(n),) + x0.shape)                       # (n, T, D)
        xt = scheduler.add_noise(torch.as_tensor(x0).expand(int(n), *x0.shape),
                                 torch.as_tensor(eps), int(t)).numpy()       # Eq. (4)
        mean = xt.mean(axis=0)
        a = float(scheduler.alphas_cumprod[int(t)])
        out["t"].append(int(t))
        out["sqrt_alpha_bar"].append(np.sqrt(a))
        out["slope"].append(float(np.sum(mean * x0) / np.sum(x0 * x0)))
        out["one_minus_alpha_bar"].append(1 - a)
        out["variance"].append(float(xt.var(axis=0, ddof=1).mean()))
    return {k: np.array(v) for k, v in out.items()}


def noising_figure(joints, ts=NOISE_LEVELS, seed=0, checkpoint=None, backend="auto"):
    """The walk ``joints`` (40, 22, 3) noised to each level of ``ts`` with one ε, decoded back
    to joints and drawn as strobes (one panel per t, titled with √ᾱ_t and the SNR).

    Returns ``(fig, decoded)`` with ``decoded`` a (K, 40, 22, 3) array."""
    gen = generator(checkpoint)
    x0 = normalized_features(joints, checkpoint)
    xt = noised_features(x0, gen.scheduler, ts, seed)
    decoded = np.stack([decode(x, checkpoint) for x in xt])
    fig, axes = _figure(len(ts), 1.5, 2.1)
    size = (240, 300)
    for ax, t, x in zip(np.atleast_1d(axes), ts, decoded):
        a = float(gen.scheduler.alphas_cumprod[int(t)])
        _show(ax, strobe_image(x, every=8, size=size, backend=backend),
              f"t = {t}\n√ᾱ = {np.sqrt(a):.2f}, SNR = {a / (1 - a):.2g}", fontsize=7)
    fig.suptitle("x_t = √ᾱ_t x_0 + √(1−ᾱ_t) ε, decoded to joints (one ε for all t)",
                 fontsize=8)
    return fig, decoded


def schedule_figure(scheduler):
    """ᾱ_t (left) and the signal-to-noise ratio SNR_t = ᾱ_t / (1 − ᾱ_t) (right, log) of
    ``scheduler`` next to DDPM's linear and the cosine schedule (T = 1000)."""
    from physlab.motion.diffusion import NoiseScheduler

    scheds = {"this model (MLD: scaled-linear β, 0.00085 → 0.012)": scheduler,
              "DDPM: linear β, 1e-4 → 0.02": NoiseScheduler(),
              "cosine (Nichol & Dhariwal)": NoiseScheduler(beta_schedule="cosine")}
    fig, (ax, ax2) = _figure(2, 4.4, 2.9)
    for (label, s), c in zip(scheds.items(), ("tab:red", "tab:blue", "tab:green")):
        a = s.alphas_cumprod.numpy()
        t = np.arange(len(a))
        ax.plot(t, a, color=c, lw=1.6, label=label)
        ax2.semilogy(t, a / (1 - a), color=c, lw=1.6)
    ax.set_xlabel("t")
    ax.set_ylabel("ᾱ_t  (signal variance kept)")
    ax.legend(fontsize=6.5, loc="upper right")
    ax2.set_xlabel("t")
    ax2.set_ylabel("SNR = ᾱ_t / (1 − ᾱ_t)")
    ax2.axhline(1.0, color="0.4", lw=0.7, ls=":")
    for a_ in (ax, ax2):
        a_.grid(alpha=0.3)
    return fig


# ---------------------------------------------------------------------------- Sec. 4: samplers
def motion_stats(joints, fps=FPS):
    """Quality numbers of one clip ``(T, 22, 3)``, or their means over the clips of a batch
    ``(B, T, 22, 3)``.

    Returns a dict of floats: ``speed`` (mean horizontal pelvis speed, m/s),
    ``foot_skating`` (GMD ratio), ``auj`` and ``pj`` (the jerk of Sketch2Anim supp. D in
    FlowMDM's definition, m/frame³, AUJ relative to HumanML3D's PJ 0.0330, as in
    :mod:`physlab.motion.evaluate`). Note: for a batch, :func:`physlab.motion.metrics.jerk`
    (and the evaluation table) takes the peak of the *mean* jerk curve; here each clip's PJ
    and AUJ are averaged, so a batch and its clips one by one give the same numbers.
    """
    x = np.asarray(joints, dtype=float)
    xb = x[None] if x.ndim == 3 else x
    jerks = np.array([M.jerk(c, reference=M.HUMANML3D_GT_PEAK_JERK) for c in xb])  # (B, 2)
    return {"speed": float(np.mean([root_speed(c, fps).mean() for c in xb])),
            "foot_skating": float(np.mean(M.foot_skating_ratio(xb, fps=fps))),
            "auj": float(jerks[:, 0].mean()), "pj": float(jerks[:, 1].mean())}


def sampler_comparison(action="a person walks", samplers=None, seed=0, guidance_scale=7.5,
                       checkpoint=None):
    """Sample the same text with the same x_T by several samplers and time them.

    Parameters
    ----------
    action : str; samplers : dict label -> (method, steps), default :data:`SAMPLERS`;
    seed : int (x_T and DDPM's step noise); guidance_scale : w of Eq. (14).

    Returns
    -------
    dict label -> dict with ``joints`` (40, 22, 3), ``seconds`` (wall time) and the numbers
    of :func:`motion_stats`.
    """
    samplers = SAMPLERS if samplers is None else samplers
    w = _check_scale(guidance_scale)
    gen = generator(checkpoint)
    out = {}
    with one_thread(), _quiet_encoder_loading(_unknown(gen, [action])):
        for label, (method, steps) in samplers.items():
            tic = time.perf_counter()
            x = gen(action, seed=seed, guidance_scale=w, steps=int(steps), method=method)
            out[label] = {"joints": x, "seconds": time.perf_counter() - tic, **motion_stats(x)}
    return out


def sampler_figure(results, real=None, backend="auto"):
    """Strobes of :func:`sampler_comparison` results (and of a ``real`` clip, if given)."""
    panels = ([("real clip", real, None)] if real is not None else []) + [
        (label, r["joints"], r) for label, r in results.items()]
    fig, axes = _figure(len(panels), 2.25, 2.3)
    for ax, (label, x, r) in zip(np.atleast_1d(axes), panels):
        st = motion_stats(x) if r is None else r
        extra = "" if r is None else f", {r['seconds']:.2g} s"
        _show(ax, strobe_image(x, size=(300, 260), backend=backend),
              f"{label}{extra}\nskating {st['foot_skating']:.2f}, PJ {st['pj']:.3f}",
              fontsize=7)
    return fig


# ---------------------------------------------------------------------------- Sec. 5: CFG
def guidance_sweep(actions=("a person walks", "a person runs"), scales=GUIDANCE_SCALES,
                   seeds=(0, 1), steps=50, checkpoint=None):
    """Motion statistics against the guidance scale w (Sketch2Anim Eq. (14)).

    Parameters
    ----------
    actions : texts; scales : guidance scales w >= 0; seeds : sampling seeds averaged over;
    steps : DDIM steps.

    Returns
    -------
    dict: ``scales`` (S,) array and, per action, a dict of (S,) arrays ``speed``,
    ``foot_skating``, ``auj``, ``pj`` (:func:`motion_stats` over the seeds).
    """
    scales = np.array([_check_scale(w) for w in scales])
    gen = generator(checkpoint)
    out = {"scales": scales}
    with one_thread(), _quiet_encoder_loading(_unknown(gen, actions)):
        for a in actions:
            rows = [motion_stats(np.stack([gen(a, seed=int(s), guidance_scale=float(w),
                                               steps=int(steps)) for s in seeds]))
                    for w in scales]
            out[a] = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    return out


def guidance_sweep_figure(sweep, real=None):
    """Mean pelvis speed, foot skating and peak jerk against w, one line per action; dashed
    lines: the same numbers of ``real`` clips (dict action -> (B, 40, 22, 3)), if given."""
    fig, axes = _figure(3, 3.0, 2.5)
    w = sweep["scales"]
    keys = (("speed", "mean pelvis speed (m/s)"), ("foot_skating", "foot-skating ratio"),
            ("pj", "peak jerk PJ (m/frame³)"))
    actions = [k for k in sweep if k != "scales"]
    colors = ("tab:blue", "tab:red", "tab:green", "tab:purple")
    for ax, (key, label) in zip(axes, keys):
        for a, c in zip(actions, colors):
            ax.plot(w, sweep[a][key], "o-", color=c, ms=3.5, lw=1.4, label=_short(a))
            if real is not None and a in real:
                ax.axhline(motion_stats(real[a])[key], color=c, lw=1.0, ls="--")
        ax.axvline(7.5, color="0.5", lw=0.7, ls=":")
        ax.set_xlabel("guidance scale w")
        ax.set_title(label, fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, title="dashed: real clips" if real is not None else None,
                   title_fontsize=6.5)
    return fig


def guidance_demo(guidance_scale=7.5, action="a person walks", seed=0, steps=50,
                  checkpoint=None, backend="auto"):
    """Widget callback: generate ``action`` with classifier-free guidance scale w =
    ``guidance_scale`` (Eq. (14): ε = ε_u + w (ε_c − ε_u); 0 = text ignored, 1 = plain
    conditional) and draw it: a strobe (left) and the pelvis speed over time (right).
    Same seed for every w, so only the guidance changes. One torch thread, ``steps`` DDIM
    steps (< 1 s with the default model)."""
    w = _check_scale(guidance_scale)
    if not isinstance(action, str) or not action.strip():
        raise ValueError(f"action must be a text such as 'a person walks', got {action!r}")
    gen = generator(checkpoint)
    with one_thread(), _quiet_encoder_loading(_unknown(gen, [action])):
        x = gen(action, seed=int(seed), guidance_scale=w, steps=int(steps))
    st = motion_stats(x)
    fig, (ax, ax2) = _figure(2, 4.2, 2.9)
    _show(ax, strobe_image(x, backend=backend), f"“{action}”, w = {w:g}")
    v = root_speed(x)
    t = np.arange(1, len(v) + 1) / FPS
    ax2.plot(t, v, color="tab:blue", lw=1.6, label="pelvis speed")
    ax2.axhline(v.mean(), color="tab:blue", lw=0.8, ls="--", label=f"mean {v.mean():.2f} m/s")
    ax2.set_ylim(0, max(3.0, 1.15 * v.max()))
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("m/s")
    ax2.legend(fontsize=7, loc="upper right")
    ax2.grid(alpha=0.3)
    ax2.set_title(f"foot skating {st['foot_skating']:.2f}, PJ {st['pj']:.3f} m/frame³",
                  fontsize=8)
    return fig


def guidance_by_level(actions=tuple(LEVEL_ACTIONS), settings=None, seeds=range(8), steps=None,
                      checkpoint=None):
    """Mean pelvis speed of text-only clips under several text guidance settings: one scale
    w for every DDIM step, or a pair ``(w_high, w_low)``, w_high at the noise levels
    ``t >= GUIDANCE_SPLIT * T`` and w_low below
    (:func:`~physlab.motion.conditions.check_guidance`).

    ``settings`` None: the generator's own text guidance (:attr:`~physlab.motion.sampling.
    Generator.text_guidance`) and, for a pair ``(h, l)``, each half's scale alone: ``(l, h,
    (h, l))``; for one scale w: ``(w, 2 w, (2 w, w))``. Same seeds for every setting.

    Returns
    -------
    dict: ``settings`` (list of floats / pairs), ``labels`` (list of str), ``speed``
    {action: (S,) array, m/s, mean over ``seeds``}, ``per_seed`` {action: (S, n_seeds)}.
    """
    from physlab.motion.conditions import check_guidance, format_guidance

    gen = generator(checkpoint)
    if settings is None:
        w = gen.text_guidance
        h, lo = w if isinstance(w, tuple) else (2 * w, w)
        settings = (lo, h, (h, lo))
    settings = [check_guidance(w, "settings") for w in settings]
    seeds = [int(s) for s in seeds]
    if not settings or not seeds:
        raise ValueError("settings and seeds must not be empty")
    steps = None if steps is None else int(steps)
    per = {}
    with one_thread(), _quiet_encoder_loading(_unknown(gen, actions)):
        for a in actions:
            per[a] = np.array([[root_speed(gen(a, seed=s, guidance_scale=w, steps=steps)).mean()
                                for s in seeds] for w in settings])
    labels = [format_guidance(w) for w in settings]
    return {"settings": settings, "labels": labels, "per_seed": per,
            "speed": {a: v.mean(1) for a, v in per.items()}}


def guidance_by_level_figure(result, real=None):
    """Bars of :func:`guidance_by_level`: one panel per action, one bar per setting (mean
    pelvis speed, the seeds as dots); dashed: the real speed, if given: ``real`` dict action
    -> a speed (m/s, e.g. :func:`real_speeds`) or real clips (B, 40, 22, 3)."""
    actions = list(result["speed"])
    fig, axes = _figure(len(actions), 3.3, 2.7)
    axes = np.atleast_1d(axes)
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:gray")
    n = len(result["labels"])
    ticks = [f"{w[0]:g} then {w[1]:g}" if isinstance(w, tuple) else f"{w:g}"
             for w in result["settings"]]
    for ax, a in zip(axes, actions):
        for i in range(n):
            ax.bar(i, result["speed"][a][i], color=colors[i % len(colors)], alpha=0.8)
            ax.plot(np.full(result["per_seed"][a].shape[1], i), result["per_seed"][a][i], ".",
                    color="k", ms=3, alpha=0.6)
        if real is not None and a in real:
            v = (float(real[a]) if np.ndim(real[a]) == 0 else motion_stats(real[a])["speed"])
            ax.axhline(v, color="k", ls="--", lw=1.0, label=f"real clips {v:.3g} m/s")
            ax.legend(fontsize=7, loc="upper left")
        ax.set_xticks(range(n))
        ax.set_xticklabels(ticks, fontsize=7)
        ax.set_xlabel("text guidance w (a pair: t ≥ T/2, then below)", fontsize=7)
        ax.set_title(f"“{a}”", fontsize=8)
        ax.set_ylabel("mean pelvis speed (m/s)", fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3, axis="y")
    return fig


# ---------------------------------------------------------------------------- Sec. 6: words
def action_speeds(actions, seeds=(0, 1), steps=None, guidance_scale=7.5, checkpoint=None):
    """Mean horizontal pelvis speed (m/s) of generated clips of each text, averaged over
    ``seeds``, with ``steps`` DDIM steps (None: ``generate``'s default) and text guidance
    ``guidance_scale`` (None: the generator's default for text only,
    :attr:`~physlab.motion.sampling.Generator.text_guidance`): dict action -> float."""
    w = None if guidance_scale is None else _check_scale(guidance_scale)
    steps = None if steps is None else int(steps)
    gen = generator(checkpoint)
    with one_thread(), _quiet_encoder_loading(_unknown(gen, actions)):
        return {a: float(np.mean([root_speed(gen(a, seed=int(s), guidance_scale=w,
                                                 steps=steps)).mean() for s in seeds]))
                for a in actions}


#: Actions whose text-only clips the control model's x₀ base overwrites with its own motion
#: (README, text-adherence finding), for :func:`text_model_comparison`.
RARE_ACTIONS = ("a person walks backwards", "a person waves the right hand", "a person bows",
                "a person raises both hands")


def text_model_comparison(actions=RARE_ACTIONS, seed=1, steps=None, checkpoint=None):
    """Text-only clips of each action, same seed, from the checkpoint's text model
    (:attr:`~physlab.motion.sampling.Generator.text_model`, what ``generate`` uses) and from
    the control model's frozen base (Sketch2Anim's text only).

    Returns dict ``{"actions": tuple, "text model": [(40, 22, 3)], "control base": [...],
    "statistics": {row: (n_actions, 5) array of evaluate.motion_statistics}}``. ValueError if
    the checkpoint has no text model."""
    from physlab.motion.evaluate import motion_statistics

    gen = generator(checkpoint)
    if gen.text_model is None:
        raise ValueError(f"{gen.path} has no text model; attach one with `python -m "
                         f"physlab.motion.checkpoint attach-text {gen.path} TEXT_BASE.pt`")
    actions = tuple(actions)
    if not actions or not all(isinstance(a, str) and a.strip() for a in actions):
        raise ValueError(f"actions must be non-empty texts, got {actions!r}")
    keep, out = gen.text_model, {"actions": actions}
    try:
        with one_thread(), _quiet_encoder_loading(_unknown(gen, actions)):
            for row, model in (("text model", keep), ("control base", None)):
                gen.text_model = model
                out[row] = [gen(a, seed=int(seed), steps=steps) for a in actions]
    finally:
        gen.text_model = keep
    out["statistics"] = {row: motion_statistics(np.stack(out[row]))
                         for row in ("text model", "control base")}
    return out


def text_model_figure(result, backend="auto"):
    """Strobes of :func:`text_model_comparison`: the text model's clips (top row) over the
    control base's (bottom), titled with the pelvis's forward travel and the wrist travel."""
    n = len(result["actions"])
    fig, axes = new_figure(n, 2, width=2.25, height=2.2)
    fig.set_dpi(FIG_DPI)
    for r, row in enumerate(("text model", "control base")):
        for c, action in enumerate(result["actions"]):
            st = result["statistics"][row][c]
            _show(axes[r * n + c], strobe_image(result[row][c], size=(300, 260), backend=backend),
                  f"{row}: {_short(action)}\nforward {st[0]:+.2f} m, wrist "
                  f"{100 * st[4]:.1f} cm/frame", fontsize=7)
    return fig


def embedding_neighbourhood(queries=UNSEEN_ACTIONS, vocabulary=None, extra=None, k=4,
                            encoder=None, checkpoint=None):
    """Cosine similarities of action texts in the text encoder's embedding space.

    Parameters
    ----------
    queries : texts whose neighbours are listed (e.g. words no training clip has).
    vocabulary : texts the neighbours come from; None = the 24 unstyled training texts
        (:func:`~physlab.motion.text.training_vocabulary`).
    extra : more texts for the scatter plot only; None = the generic actions of
        :data:`~physlab.motion.text.GENERIC_ACTIONS` (minus the queries).
    k : neighbours per query.
    encoder : None = the checkpoint's :class:`~physlab.motion.text.EmbeddingCache` (the exact
        vectors the model was trained with; unknown texts are encoded by its encoder, the
        offline MiniLM for a real checkpoint), or any ``list[str] -> (N, D)`` callable.

    Returns
    -------
    dict: ``vocabulary`` / ``queries`` / ``extra`` lists of str, ``V`` (N, D), ``Q`` (q, D),
    ``X`` (e, D) unit rows, ``S`` (q, N) cosines of queries to vocabulary, ``neighbours``
    dict query -> list of k ``(text, cosine)``, most similar first.
    """
    from physlab.motion.text import GENERIC_ACTIONS, cosine_similarity, training_vocabulary

    vocabulary = training_vocabulary() if vocabulary is None else list(vocabulary)
    queries = list(queries)
    extra = [t for t in GENERIC_ACTIONS if t not in queries] if extra is None else list(extra)
    if not vocabulary or not queries:
        raise ValueError("vocabulary and queries must be non-empty lists of texts")
    enc = generator(checkpoint).text_cache if encoder is None else encoder
    with one_thread(), _quiet_encoder_loading():
        E = np.asarray(enc(vocabulary + queries + extra), dtype=float)
    E /= np.linalg.norm(E, axis=1, keepdims=True)
    V, Q, X = np.split(E, [len(vocabulary), len(vocabulary) + len(queries)])
    S = cosine_similarity(Q, V)                                               # (q, N)
    order = np.argsort(-S, axis=1, kind="stable")[:, :int(k)]
    nbrs = {q: [(vocabulary[j], float(S[i, j])) for j in order[i]]
            for i, q in enumerate(queries)}
    return {"vocabulary": vocabulary, "queries": queries, "extra": extra, "V": V, "Q": Q,
            "X": X, "S": S, "neighbours": nbrs}


def _labels_without_overlap(ax, points, labels, colours, fontsize=6.5, pad=1.0, avoid=()):
    """Annotate ``points`` (n, 2) with ``labels`` in the given order of priority, skipping
    any label whose box would overlap an already placed label, a box of ``avoid`` (display
    coordinates) or leave the axes. Returns the number of labels placed."""
    ax_box = ax.get_window_extent()
    placed = list(avoid)
    for (px, py), text, c in zip(points, labels, colours):
        ann = ax.annotate(text, (px, py), fontsize=fontsize, color=c, xytext=(3, 2),
                          textcoords="offset points")
        box = ann.get_window_extent().expanded(pad, pad)
        inside = ax_box.x0 <= box.x0 and box.x1 <= ax_box.x1 and ax_box.y0 <= box.y0 \
            and box.y1 <= ax_box.y1
        if not inside or any(box.overlaps(b) for b in placed):
            ann.remove()
        else:
            placed.append(box)
    return len(placed) - len(avoid)


def embedding_figure(nb, label_every=1):
    """Left: each query's nearest training texts (cosine bars); right: all texts projected
    on the two first principal components of their embeddings (training texts blue,
    queries red, other unseen texts orange), labelled where labels do not overlap (queries
    and their neighbours first)."""
    q = len(nb["queries"])
    fig, (ax, ax2) = _figure(2, 4.5, 3.4, width_ratios=(0.8, 1.2))
    colors = ("tab:red", "tab:purple", "tab:brown", "tab:pink")
    y, ticks = 0.0, []
    for i, query in enumerate(nb["queries"]):
        ax.text(0.01, y, f"neighbours of “{_short(query)}”:", fontsize=7.5,
                color=colors[i % 4], weight="bold", va="center")
        y -= 1
        for text, cos in nb["neighbours"][query]:
            ax.barh(y, cos, color=colors[i % 4], alpha=0.75)
            ax.text(cos + 0.01, y, f"{cos:.2f}", fontsize=6.5, va="center")
            ticks.append((y, _short(text)))
            y -= 1
        y -= 0.4
    ax.set_yticks([p for p, _ in ticks], [s for _, s in ticks], fontsize=6.5)
    ax.set_xlabel("cosine similarity")
    ax.set_xlim(0, 1)
    ax.set_ylim(y + 0.4, 0.6)
    ax.grid(axis="x", alpha=0.3)
    ax.set_title(f"nearest training texts of {q} unseen texts", fontsize=8)
    E = np.concatenate([nb["V"], nb["Q"], nb["X"]])
    Ec = E - E.mean(axis=0)
    _, s, Vt = np.linalg.svd(Ec, full_matrices=False)
    P = Ec @ Vt[:2].T                                                        # (n, 2)
    var = s[:2] ** 2 / np.sum(s ** 2)
    nv, nq = len(nb["V"]), len(nb["Q"])
    groups = ((slice(0, nv), "tab:blue", "training texts"),
              (slice(nv + nq, None), "tab:orange", "other unseen texts"),
              (slice(nv, nv + nq), "tab:red", "queries"))
    texts = nb["vocabulary"] + nb["queries"] + nb["extra"]
    colour = np.empty(len(texts), dtype=object)
    for sl, c, lab in groups:
        ax2.scatter(*P[sl].T, s=14 if c != "tab:red" else 30, color=c, label=lab, zorder=3)
        colour[sl] = c
    # Label what the left panel talks about first (queries, then their neighbours), then the
    # rest while there is room: a label that would overlap a placed one is left out.
    ax2.set_xlabel(f"PC 1 ({100 * var[0]:.0f} % of variance)")
    ax2.set_ylabel(f"PC 2 ({100 * var[1]:.0f} %)")
    legend = ax2.legend(fontsize=6.5, loc="best")
    ax2.set_title("action-text embeddings, 2-D PCA", fontsize=8)
    ax2.grid(alpha=0.3)
    near = {t for q in nb["queries"] for t, _ in nb["neighbours"][q]}
    order = sorted(range(len(texts))[::label_every],
                   key=lambda i: (texts[i] not in nb["queries"], texts[i] not in near, i))
    fig.draw_without_rendering()                          # fix the layout, then place labels
    _labels_without_overlap(ax2, P[order], [_short(texts[i]) for i in order], colour[order],
                            avoid=[legend.get_window_extent()])
    return fig


# ---------------------------------------------------------------------------- Sec. 7: control
def condition_kwargs(cond):
    """:meth:`Condition.generator_kwargs <physlab.motion.dataset.Condition.generator_kwargs>`
    of ``cond`` (the lesson's name for it)."""
    return cond.generator_kwargs()


#: Rows of :func:`control_comparison`: key -> (row name of :mod:`physlab.motion.evaluate`,
#: panel title).
CONTROL_ROWS = {
    "text_only": ("text only", "text only"),
    "controlled": ("keypose + trajectory", "ControlNet + adapter (Eqs. 1–4)"),
    "guided": ("keypose + trajectory + guidance", "+ inference guidance"),
}


def _held_out(windows, data_root, held_out_windows):
    """``windows`` held-out windows: evenly spaced ones of the shipped :func:`lesson_windows`
    when ``data_root`` is None and ``windows`` <= :data:`LESSON_HELD_OUT`, else
    :func:`~physlab.motion.evaluate.held_out_windows` on the clips."""
    if isinstance(windows, bool) or not float(windows).is_integer() or windows < 1:
        raise ValueError(f"windows must be an integer >= 1, got {windows!r}")
    n = int(windows)
    if data_root is None and n <= LESSON_HELD_OUT:
        w = lesson_windows()
        idx = np.round(np.linspace(0, len(w["held_out"]) - 1, n)).astype(int)
        return {"joints": w["held_out"][idx], "text": [str(t) for t in w["held_out_text"][idx]],
                "clip_id": [str(c) for c in w["held_out_clip_id"][idx]]}
    return held_out_windows(n, data_root=_bandai_dir(
        data_root, f"control_comparison(windows={n}) (more than the {LESSON_HELD_OUT} shipped)"))


def control_comparison(windows=6, seed=0, steps=50, guidance_scale=7.5, checkpoint=None,
                       data_root=None, body_constraints=True):
    """Text only vs. keypose + trajectories on held-out windows.

    ``windows`` held-out take-002 windows (:func:`~physlab.motion.evaluate.held_out_windows`;
    up to :data:`LESSON_HELD_OUT` of them are shipped, see :func:`_held_out`) with one
    Sketch2Anim "Cross" condition each (:func:`~physlab.motion.evaluate.eval_conditions`:
    keypose first / last, random ``t_r`` and joint subset). Window ``i`` is
    generated from its text with seed ``seed + i`` (the same x_T) three times:

    * ``text_only`` — the frozen text model, no keypose / trajectories;
    * ``controlled`` — keypose + trajectories through the trajectory ControlNet and the
      keypose adapter alone (Eqs. (1)–(4); :data:`~physlab.motion.evaluate.UNGUIDED`);
    * ``guided`` — the same plus the inference guidance (Sketch2Anim supp. C: L-BFGS on the
      last x̂₀ against the decoded keypose / trajectory losses, Eqs. (6), (8);
      :data:`~physlab.motion.evaluate.GUIDED`).

    ``guidance_scale`` is the text scale of the text-only clips; the controlled ones use the
    generator's default under control (:data:`~physlab.motion.sampling.
    CONTROL_TEXT_GUIDANCE`). ``body_constraints`` is passed to the generator (rigid bones,
    feet above the floor).

    Returns
    -------
    dict: ``real`` / ``text_only`` / ``controlled`` / ``guided`` (n, 40, 22, 3) arrays,
    ``conds`` list of :class:`Condition`, ``text`` / ``clip_id`` lists of str, ``rows`` dict
    row name -> :func:`~physlab.motion.evaluate.clip_metrics` dict (``"real clips"`` and the
    row names of :data:`CONTROL_ROWS`), ``per_window`` dict key of :data:`CONTROL_ROWS` ->
    (n, 2) array of (keypose MPJPE, trajectory error) per window (m).
    """
    from physlab.motion.dataset import TRAJECTORY_JOINTS
    from physlab.motion.evaluate import (
        GUIDED,
        UNGUIDED,
        clip_metrics,
        eval_conditions,
        held_out_windows,
    )

    w = _check_scale(guidance_scale)
    gen = generator(checkpoint)
    if not gen.has_control:
        raise ValueError(f"{gen.path} is a '{gen.stage}' checkpoint; keypose / trajectory "
                         f"control needs a control checkpoint (train --stage control)")
    data = _held_out(windows, data_root, held_out_windows)
    conds = eval_conditions(data["joints"], seed=seed)
    out = {"real": data["joints"], "conds": conds, "text": data["text"],
           "clip_id": data["clip_id"]}
    options = {"text_only": None, "controlled": UNGUIDED, "guided": GUIDED}
    rows = {"real clips": clip_metrics(out["real"], conds)}
    with one_thread():
        for key, opts in options.items():
            xs, tic = [], time.perf_counter()
            for i, c in enumerate(conds):
                kw = {} if opts is None else {**condition_kwargs(c), **opts}
                xs.append(gen(data["text"][i], seed=seed + i,
                              guidance_scale=w if opts is None else None,   # control: w = 1
                              steps=int(steps), body_constraints=body_constraints, **kw))
            out[key] = np.stack(xs)
            rows[CONTROL_ROWS[key][0]] = clip_metrics(
                out[key], conds, (time.perf_counter() - tic) / len(conds))
    out["rows"] = rows
    out["per_window"] = {
        key: np.array([[M.mpjpe(x[c.key_frame], c.keypose),
                        M.trajectory_error(x, c.trajectory, TRAJECTORY_JOINTS, c.mask)]
                       for x, c in zip(out[key], conds)]) for key in options}
    return out


def control_figure(result, index=0, backend="auto"):
    """Held-out window ``index`` of :func:`control_comparison`: the real clip and the three
    samples (text only, ControlNet + adapter, + inference guidance), each with the keypose
    (red) and the trajectories (green) of the condition."""
    c = result["conds"][index]
    kw = condition_kwargs(c)
    fig, axes = _figure(4, 2.25, 2.6)
    panels = [("real", "real (held out)")] + [(k, t) for k, (_, t) in CONTROL_ROWS.items()]
    for ax, (key, title) in zip(axes, panels):
        err = ""
        if key != "real":
            kp, tr = result["per_window"][key][index]
            err = f"\nkeypose {100 * kp:.1f} cm, traj. {100 * tr:.1f} cm"
        _show(ax, strobe_image(result[key][index], every=8, size=(300, 280), keypose=c.keypose,
                               keypose_frame=c.key_frame, trajectories=kw["trajectories_3d"],
                               backend=backend), title + err, fontsize=7)
    joints = ", ".join(kw["trajectories_3d"])
    fig.suptitle(f"“{result['text'][index]}”: keypose at frame {c.key_frame + 1}/40, "
                 f"{c.t_r}-frame trajectories of {joints}", fontsize=8)
    return fig


# ---------------------------------------------------------------------------- Sec. 8: BVH
def export_bvh(joints, path, fps=FPS):
    """Write a clip as BVH (:func:`physlab.motion.export.joints_to_bvh`), read it back and
    measure how well the rigid BVH skeleton reproduces the joints.

    A generated clip is not exactly rigid (its bone lengths drift a little from frame to
    frame), so the BVH holds the closest rigid skeleton; the library's warning about that is
    replaced by the returned error.

    Returns
    -------
    (path, max_error_m, bone_length_std_m): the written Path, the largest joint-position
    error of the read-back file (m), and the mean over bones of the std of each bone's length
    over the frames (m).
    """
    from physlab.motion import joints_to_bvh, read_bvh
    from physlab.motion.skeleton import bone_lengths

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="the BVH reproduces the joints only")
        path = joints_to_bvh(joints, path, fps=fps)
    m = read_bvh(path)
    back = m.joint_positions()[:, [m.joint_index(n) for n in JOINT_NAMES]]    # (T, 22, 3)
    err = float(np.linalg.norm(back - np.asarray(joints), axis=-1).max())
    L = bone_lengths(np.asarray(joints))
    return path, err, float(np.std(L, axis=0).mean())
