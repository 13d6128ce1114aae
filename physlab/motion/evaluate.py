"""Held-out evaluation of the motion generator (the analogue of Sketch2Anim Table 2 / A1-A4).

Test set: the Bandai-Namco take-002 clips (:func:`~physlab.motion.dataset.split_by_take`),
cut into canonical 40-frame windows (:func:`~physlab.motion.dataset.make_windows`, stride
10); ``windows`` of them are taken at evenly spaced indices (deterministic, spread over the
clips). Each window ``i`` gets one condition (:func:`~physlab.motion.dataset.
condition_from_window`), Sketch2Anim's "Cross" protocol (Sec. 7.1, after OmniControl):

* keypose at the **first** frame for even ``i``, the **last** frame for odd ``i``;
* ``t_r`` uniform in ``MIN_T_R .. 40`` and one of the 63 joint combinations
  (:data:`~physlab.motion.dataset.JOINT_COMBINATIONS`, uniform), both drawn from
  ``np.random.default_rng(seed)`` in window order — the same conditions for every row;
* the text is the window's action text, the sampling seed of window ``i`` is ``seed + i``.

Rows of the table:

* ``real clips`` — the held-out windows themselves (keypose / trajectory errors are 0 by
  definition: the condition is cut from the window);
* ``text only`` — the text denoiser of the ``--control`` checkpoint (its frozen base), no
  keypose / trajectories; its keypose and trajectory errors are measured against the same
  conditions (how far an unconditioned motion lands from the target);
* ``keypose + trajectory`` — the full conditioning by the networks alone (trajectory
  ControlNet + keypose adapter, :class:`~physlab.motion.sampling.Generator` with the
  inference guidance off);
* ``keypose + trajectory + guidance`` — the same plus the inference guidance (L-BFGS
  post-optimisation of the last x̂₀, :data:`GUIDED`; the default of ``generate``);
* ``single ControlNet`` (and ``+ guidance``) — the Table 2 ablation, only with
  ``--single-controlnet CKPT``;
* ``double ControlNet`` (and ``+ guidance``) — Table 2's other ablation (a keypose
  ControlNet beside the trajectory one, residuals added), only with ``--double-controlnet
  CKPT``. The paper's ablations run without inference guidance.

Columns (:mod:`physlab.motion.metrics`):

* foot-skating ratio (GMD), mean over clips;
* keypose MPJPE-3D (m) at the key frame, mean over clips (Sketch2Anim "MPJPE-3D"), in two
  forms: ``placed`` compares absolute positions (so it includes where the clip put the pose on
  the floor), ``pose`` first moves the keypose horizontally under the clip's pelvis
  (:func:`~physlab.motion.metrics.mpjpe` with ``root_relative="xz"``). A Sketch2Anim keypose
  "does not provide global positional information" (Sec. 3); for a last-frame keypose its
  placement comes only from the trajectories, so ``pose`` is the error of the pose the user
  drew and ``placed`` adds the trajectory error at that frame;
* trajectory error (m): mean distance over all controlled (frame, joint) points of all
  clips, OmniControl's ``sum / mask.sum()`` ("Avg. Err.-3D");
* AUJ and PJ (supp. D, Tab. A4, FlowMDM's definitions): the jerk curve averaged over the
  clips, ``PJ`` its peak, ``AUJ = sum_t |jbar_t - 0.0330|`` (reference
  :data:`~physlab.motion.metrics.HUMANML3D_GT_PEAK_JERK`, per-frame units, as published).
  Sketch2Anim evaluates them on the 20 blended frames; here on whole 40-frame clips, so
  compare rows with the ``real clips`` row, not with the paper;
* body checks: ``bone std`` the largest over clips of the worst bone's length std over
  frames (m); ``feet < −2 cm`` the mean fraction of frames with a foot joint more than 2 cm
  below the floor; ``edge step ratio`` the largest over clips with a partial trajectory of
  the joint step where the trajectory starts or ends divided by the clip's median step
  (issue 12's bound), ``edge jump`` the same step over the joint's own neighbouring steps
  (about 1 where the motion is merely fast there, e.g. a waving wrist; large for a jump;
  :func:`~physlab.motion.metrics.boundary_jump_ratio`);
* seconds per clip: wall time of one :class:`~physlab.motion.sampling.Generator` call
  (``steps`` DDIM steps, CFG as a batch of 2); 0 for the real clips.

With the shipped text–motion evaluator (:mod:`~physlab.motion.evaluator`, TMR-style,
trained here on the training takes; ``--no-evaluator`` skips it): FID of each row's clips
against the *other* held-out windows (the real row's FID is the small-sample floor),
R-precision top-3 in batches of 32 (duplicate texts merged; chance printed under the
table), MM-Dist and Diversity (Guo et al. 2022's definitions), all in the evaluator's unit-
sphere embedding, so not comparable with HumanML3D numbers.

Usage::

    python -m physlab.motion.evaluate --control runs/control.pt \\
        [--single-controlnet runs/single.pt] [--double-controlnet runs/double.pt] [--windows 64] [--steps 25] [--guidance W] [--control-guidance 1] \\
        [--seed 0] [--out runs/eval] [--no-progress] [--pose-detail]

    from physlab.motion.evaluate import evaluate
    rows = evaluate("runs/control.pt", windows=64)     # {"real clips": {...}, ...}

Data: Bandai-Namco-Research-Motiondataset, CC BY-NC 4.0, © 2022 Bandai Namco Research Inc.
"""
from __future__ import annotations

import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from physlab._io import atomic_write_text

from .blend import TRANSITION, blend, junction_step_ratio
from .conditions import check_guidance, format_guidance, guidance_argument
from .dataset import (
    ACTION_PHRASES,
    BANDAI_NAMCO_ATTRIBUTION,
    action_text,
    JOINT_COMBINATIONS,
    TEST_TAKES,
    TRAJECTORY_JOINTS,
    condition_from_window,
    load_clips,
    make_windows,
    read_labels,
    split_by_take,
)
from .metrics import (
    HUMANML3D_GT_PEAK_JERK,
    bone_length_variation,
    boundary_jump_ratio,
    boundary_step_ratio,
    floor_penetration,
    foot_skating_ratio,
    jerk,
    mpjpe,
    trajectory_error,
)
from .features import _rotate_y, root_heading
from .skeleton import joint_index

__all__ = [
    "phase_change_score", "blending_windows", "evaluate_blending", "format_blending_table",
    "BLEND_ROWS",
    "COLUMNS",
    "EVALUATOR_COLUMNS",
    "MIN_T_R",
    "GUIDANCE_VARIANTS",
    "ROW_NAMES",
    "VARIANTS",
    "clip_metrics",
    "eval_conditions",
    "evaluate",
    "DETAIL_LEVELS",
    "detail_kept",
    "follow_slope",
    "format_adherence",
    "format_detail",
    "format_table",
    "held_out_windows",
    "main",
    "motion_statistics",
    "POSE_GROUPS",
    "facing",
    "format_pose_breakdown",
    "pose_breakdown",
    "text_adherence",
]

#: Rows of the table, in order (the "single ControlNet" rows only with a second checkpoint).
ROW_NAMES = ("real clips", "text only", "keypose + trajectory",
             "keypose + trajectory + guidance", "single ControlNet",
             "single ControlNet + guidance", "double ControlNet", "double ControlNet + guidance")
#: The Table 2 variants: evaluate's keyword and CLI flag -> (row name, the variant its
#: checkpoint must hold, as :func:`physlab.motion.model.controlnet_variant` names it).
VARIANTS = {"--control": ("keypose + trajectory", "adapter"),
            "--single-controlnet": ("single ControlNet", "single"),
            "--double-controlnet": ("double ControlNet", "double")}
#: Generator options of the "+ guidance" rows (post-optimisation of the last x̂₀) and of the
#: network-only rows.
GUIDED = {"inference_guidance": 0, "guidance_final": 40}
UNGUIDED = {"inference_guidance": 0, "guidance_final": 0}
#: Per-step inference guidance variants (Table A3's analogue, ``--guidance-variants``): K = 4
#: iterations per denoising step through the network (``guidance_space="network"``, the
#: paper's form of Eqs. (15)-(16) in 3D), first-order (Adam steps) or L-BFGS, no final
#: post-optimisation.
GUIDANCE_VARIANTS = {
    "+ first-order guidance per step": {"inference_guidance": 4, "guidance_final": 0,
                                        "guidance_space": "network",
                                        "guidance_optimizer": "gradient"},
    "+ L-BFGS guidance per step": {"inference_guidance": 4, "guidance_final": 0,
                                   "guidance_space": "network", "guidance_optimizer": "lbfgs"},
}
#: Keys of every row -> column header of the table.
COLUMNS = {
    "foot_skating": "foot skating ↓",
    "keypose_mpjpe_3d": "keypose MPJPE-3D, placed (m) ↓",
    "keypose_pose_3d": "keypose pose err. (m) ↓",
    "trajectory_error_3d": "traj. err.-3D (m) ↓",
    "auj": "AUJ ↓",
    "pj": "PJ",
    "bone_variation": "bone std (m) ↓",
    "floor_penetration": "feet < −2 cm ↓",
    "boundary_step_ratio": "edge step ratio ↓",
    "boundary_jump_ratio": "edge jump ↓",
    "seconds_per_clip": "s / clip",
}
#: Columns of the shipped text–motion evaluator (:mod:`~physlab.motion.evaluator`), only
#: when :func:`evaluate` has one.
EVALUATOR_COLUMNS = {
    "fid": "FID ↓",
    "r_precision_top3": "R-prec. top-3 ↑",
    "mm_dist": "MM-Dist ↓",
    "diversity": "Diversity →",
}
#: Fewest windows the evaluator's columns are computed for (R-precision top-3 ranks >= 3).
MIN_EVALUATOR_WINDOWS = 3
#: Shortest trajectory drawn for a test condition (frames), as in training.
MIN_T_R = 5
WINDOW_LENGTH = 40
WINDOW_STRIDE = 10


# ----------------------------------------------------------------------------- test data


def held_out_windows(windows=64, data_root=None, takes=TEST_TAKES):
    """``windows`` held-out 40-frame windows at evenly spaced indices.

    Parameters
    ----------
    windows : int >= 1; more than available -> all of them (with a warning).
    data_root : None or the Bandai-Namco folder (:func:`~physlab.motion.dataset.
        bandai_namco_dir`).
    takes : the takes to draw from (default :data:`~physlab.motion.dataset.TEST_TAKES`, the
        held-out one; a training take such as ``("003",)`` shows what the model fits).

    Returns
    -------
    dict: ``joints`` (n, 40, 22, 3) float64 canonical windows (m), ``text`` list of n str,
    ``clip_id`` list of n str, ``start`` (n,) int, ``reference_joints`` (m, 40, 22, 3) the
    other held-out windows (FID's real reference; the chosen ones if fewer than 2 remain),
    ``n_available`` int.
    """
    n = _check_windows(windows)
    takes = _check_takes(takes)
    labels = read_labels(data_root)
    ids = [Path(r["file"]).stem for r in labels if r["take"] in takes]
    if not ids:
        raise ValueError(f"no clips of take {', '.join(takes)} in the labels.csv of "
                         f"{data_root or 'the Bandai-Namco data'}; takes there: "
                         f"{', '.join(sorted({r['take'] for r in labels}))}")
    _, test = split_by_take(load_clips(data_root, clip_ids=ids), test_takes=takes)
    win = make_windows(test, length=WINDOW_LENGTH, stride=WINDOW_STRIDE)
    M = len(win)
    if n > M:
        warnings.warn(f"only {M} held-out windows exist; evaluating all of them instead of "
                      f"{n}")
        n = M
    idx = np.round(np.linspace(0, M - 1, n)).astype(int)                   # distinct, n <= M
    rest = np.setdiff1d(np.arange(M), idx)
    return {"joints": win.joints[idx], "text": [win.text[i] for i in idx],
            "clip_id": [win.clip_id[i] for i in idx], "start": win.start[idx],
            "reference_joints": win.joints[rest if len(rest) >= 2 else idx],
            "n_available": M}


def eval_conditions(joints, seed=0):
    """One Sketch2Anim "Cross" condition per window (module docstring).

    Parameters
    ----------
    joints : (n, 40, 22, 3) float array of windows (m).
    seed : int, seeds ``t_r`` and the joint combination.

    Returns
    -------
    list of n :class:`~physlab.motion.dataset.Condition`.
    """
    rng = np.random.default_rng(seed)
    conds = []
    for i, w in enumerate(joints):
        t_r = int(rng.integers(MIN_T_R, len(w) + 1))
        combo = JOINT_COMBINATIONS[int(rng.integers(len(JOINT_COMBINATIONS)))]
        conds.append(condition_from_window(w, t_r=t_r, keypose_at="first" if i % 2 == 0
                                           else "last", joints=combo))
    return conds


# ----------------------------------------------------------------------------- metrics


def clip_metrics(motions, conds, seconds=0.0):
    """One table row from ``n`` clips and their conditions.

    Parameters
    ----------
    motions : (n, 40, 22, 3) float array (m), generated (or real) clips.
    conds : list of n :class:`Condition`.
    seconds : float, mean seconds per clip.

    Returns
    -------
    dict with the keys of :data:`COLUMNS` (floats) and ``n_clips``.
    """
    x = np.asarray(motions, dtype=float)
    key = np.stack([x[i, c.key_frame] for i, c in enumerate(conds)])       # (n, 22, 3)
    K = np.stack([c.keypose for c in conds])                               # (n, 22, 3)
    auj, pj = jerk(x, reference=HUMANML3D_GT_PEAK_JERK)
    ratios = [r for r in (boundary_step_ratio(m, c.mask) for m, c in zip(x, conds))
              if np.isfinite(r)]                                   # clips with a partial stroke
    jumps = [r for r in (boundary_jump_ratio(m, c.mask) for m, c in zip(x, conds))
             if np.isfinite(r)]
    return {
        "foot_skating": float(np.mean(foot_skating_ratio(x))),
        "keypose_mpjpe_3d": mpjpe(key, K),                 # equal joints per clip: mean of means
        "keypose_pose_3d": mpjpe(key, K, root_relative="xz"),   # the pose, wherever it stands
        "trajectory_error_3d": trajectory_error(
            x, np.stack([c.trajectory for c in conds]), TRAJECTORY_JOINTS,
            np.stack([c.mask for c in conds])),            # pooled over controlled points
        "auj": auj, "pj": pj,
        "bone_variation": float(np.max(bone_length_variation(x))),
        "floor_penetration": float(np.mean(floor_penetration(x))),
        "boundary_step_ratio": max(ratios) if ratios else float("nan"),
        "boundary_jump_ratio": max(jumps) if jumps else float("nan"),
        "seconds_per_clip": float(seconds), "n_clips": len(x),
    }


#: Joint groups of :func:`pose_breakdown` (names of :data:`~physlab.motion.skeleton.JOINT_NAMES`).
POSE_GROUPS = {
    "pelvis": ("pelvis",),
    "spine, neck, head": ("spine1", "spine2", "spine3", "neck", "head"),
    "collars, shoulders": ("left_collar", "right_collar", "left_shoulder", "right_shoulder"),
    "elbows, wrists": ("left_elbow", "right_elbow", "left_wrist", "right_wrist"),
    "hips, knees": ("left_hip", "right_hip", "left_knee", "right_knee"),
    "ankles, feet": ("left_ankle", "right_ankle", "left_foot", "right_foot"),
}


def facing(joints):
    """Facing yaw (degrees, about +y) of poses ``(..., 22, 3)``: the heading of
    :func:`~physlab.motion.features.root_heading` (hips and shoulders, the definition the
    windows are canonicalised with), for any leading shape. The body faces
    ``(sin θ, 0, cos θ)``, so 0 is the canonical window's ``+z`` (frame 0) and a positive
    angle turns towards ``+x`` (the body's left at θ = 0)."""
    p = np.asarray(joints, dtype=float)
    if p.ndim < 2 or p.shape[-2:] != (22, 3):
        raise ValueError(f"joints must have shape (..., 22, 3), got {p.shape}")
    return np.degrees(root_heading(p.reshape(-1, 22, 3))).reshape(p.shape[:-2])


def _wrap_degrees(a):
    return (np.asarray(a, dtype=float) + 180.0) % 360.0 - 180.0


def pose_breakdown(motions, conds, real=None):
    """Where a keypose pose error (``keypose_pose_3d`` of :func:`clip_metrics`) comes from.

    The pose error is the mean over clips and joints of the key-frame distance after the
    keypose is moved horizontally under the clip's pelvis. This splits it by clip (a few
    bad clips or all a little), by key frame (first / last), by joint group
    (:data:`POSE_GROUPS`), and into facing and posture: ``yaw_removed`` is the error left
    after each clip's pose is turned about the vertical through its pelvis by the yaw that
    fits the keypose best (least squares). For key frames after frame 0 the *turn* from
    frame 0 to the key frame (:func:`facing`) is compared with the keypose's: ``turn_slope``
    is the least-squares slope through 0 of the clips' turns on the real ones (1: the clip
    turns as far as the keypose asks; 0: not at all), ``turn_error`` the mean absolute
    difference (degrees).

    Parameters
    ----------
    motions : (n, N, 22, 3) clips (m); conds : n :class:`~physlab.motion.dataset.Condition`.
    real : None or the (n, N, 22, 3) windows the conditions were made from: the keypose's
        turn is measured from the real frame 0 (None: from the canonical ``+z``, which a
        window's frame 0 faces up to the hip line's ±10°).

    Returns
    -------
    dict: ``pose`` (m, equal to ``keypose_pose_3d``), ``clip_median``, ``clip_p90``,
    ``clip_max`` (per-clip means, m), ``first`` / ``last`` (mean over clips keyed at frame 0
    / at a later frame; NaN if none), ``yaw_removed`` (m), ``groups`` {name: m},
    ``turn_slope``, ``turn_error`` (degrees) and ``n_turn`` (clips keyed after frame 0).
    """
    x = np.asarray(motions, dtype=float)
    if x.ndim != 4 or x.shape[2:] != (22, 3) or len(x) != len(conds) or not len(x):
        raise ValueError(f"motions must be (n, N, 22, 3) with one condition per clip, got "
                         f"shape {x.shape} and {len(conds)} conditions")
    n = len(x)
    kf = np.array([c.key_frame for c in conds])
    p = x[np.arange(n), kf].copy()                                          # (n, 22, 3)
    g = np.stack([np.asarray(c.keypose, dtype=float) for c in conds])
    p[..., [0, 2]] -= p[:, :1, [0, 2]]
    g = g.copy()
    g[..., [0, 2]] -= g[:, :1, [0, 2]]
    e = np.linalg.norm(p - g, axis=-1)                                      # (n, 22)
    clip = e.mean(1)
    a = (g[..., 0] * p[..., 0] + g[..., 2] * p[..., 2]).sum(1)             # best yaw: argmax
    b = (g[..., 0] * p[..., 2] - g[..., 2] * p[..., 0]).sum(1)             # of cos·a + sin·b
    turned = _rotate_y(p, np.arctan2(b, a))
    later = kf > 0
    out = {"pose": float(e.mean()), "clip_median": float(np.median(clip)),
           "clip_p90": float(np.quantile(clip, 0.9)), "clip_max": float(clip.max()),
           "first": float(clip[~later].mean()) if (~later).any() else float("nan"),
           "last": float(clip[later].mean()) if later.any() else float("nan"),
           "yaw_removed": float(np.linalg.norm(turned - g, axis=-1).mean()),
           "groups": {name: float(e[:, [joint_index(j) for j in joints]].mean())
                      for name, joints in POSE_GROUPS.items()},
           "turn_slope": float("nan"), "turn_error": float("nan"), "n_turn": int(later.sum())}
    if later.any():
        start = (facing(np.asarray(real, dtype=float)[:, 0]) if real is not None
                 else np.zeros(n))
        want = _wrap_degrees(facing(np.stack([c.keypose for c in conds])) - start)[later]
        made = _wrap_degrees(facing(p) - facing(x[:, 0]))[later]
        out["turn_error"] = float(np.abs(_wrap_degrees(made - want)).mean())
        if np.any(want != 0):
            out["turn_slope"] = float((want * made).sum() / (want ** 2).sum())
    return out


def format_pose_breakdown(rows):
    """Markdown table of the rows of :func:`evaluate` that carry a ``pose_breakdown``."""
    rows = {k: r["pose_breakdown"] for k, r in rows.items() if "pose_breakdown" in r}
    if not rows:
        return ""
    groups = list(POSE_GROUPS)
    head = (["method", "pose err. (m)", "clip median", "clip p90", "clip max", "key frame 0",
             "later key frame", "best yaw removed"] + groups
            + ["turn slope", "turn err. (°)"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, b in rows.items():
        vals = ([b[k] for k in ("pose", "clip_median", "clip_p90", "clip_max", "first", "last",
                                "yaw_removed")] + [b["groups"][k] for k in groups])
        lines.append("| " + " | ".join([name] + [f"{v:.4f}" for v in vals]
                                       + [f"{b['turn_slope']:.2f}", f"{b['turn_error']:.1f}"])
                     + " |")
    n_turn = next(iter(rows.values()))["n_turn"]
    lines.append("")
    lines.append(f"Key-frame pose error split by clip, key frame and joint group; the turn "
                 f"columns compare the clip's turn from frame 0 to a later key frame with the "
                 f"keypose's ({n_turn} clips; slope 1 = turns as far as asked).")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- evaluate


def _check_takes(takes):
    if isinstance(takes, str):
        takes = (takes,)
    takes = tuple(takes)
    if not takes or not all(isinstance(t, str) and t for t in takes):
        raise ValueError(f"takes must be a non-empty list of take names such as '002', got "
                         f"{takes!r}")
    return takes


def _takes_note(takes):
    """"held-out windows (take 002)" or, for takes the models were trained on, says so."""
    if set(takes) <= set(TEST_TAKES):
        return f"held-out windows (take {', '.join(takes)})"
    return f"windows of take {', '.join(takes)} (not held out: the models trained on it)"


def _check_windows(windows):
    if isinstance(windows, bool) or not isinstance(windows, (int, np.integer)) or windows < 1:
        raise ValueError(f"windows must be an integer >= 1 (number of held-out clips to "
                         f"evaluate, e.g. 64), got {windows!r}")
    return int(windows)


def _load(path, flag, need_control=True, text_model=True):
    """The :class:`~physlab.motion.sampling.Generator` of checkpoint ``path`` (``flag`` names
    it in errors); ``text_model`` False drops an attached text model (text only then comes
    from the control model's base, as in Sketch2Anim)."""
    from .sampling import Generator

    if path is None or not Path(path).is_file():
        raise FileNotFoundError(
            f"{flag} checkpoint {path} does not exist; train one with `python -m "
            f"physlab.motion.train --stage base --out runs/base.pt` then `python -m "
            f"physlab.motion.train --stage control --base-ckpt runs/base.pt --out {path}`"
            + (f" {flag}" if VARIANTS.get(flag, (None, "adapter"))[1] != "adapter" else "")
            + " (add --smoke for a seconds-long test model)")
    gen = Generator.from_checkpoint(path)
    if not text_model:
        gen.text_model = None
    if not gen.has_control:
        if not need_control:
            return gen
        raise ValueError(f"{flag} {path} is a '{gen.stage}' (text-only) checkpoint; give a "
                         f"control checkpoint (`python -m physlab.motion.train --stage control "
                         f"--base-ckpt {path} --out runs/control.pt`)")
    trained = gen.model.variant
    if flag in VARIANTS and VARIANTS[flag][1] != trained:
        row, wanted = VARIANTS[flag]
        from .model import controlnet_variant_label as label
        warnings.warn(f"{flag} {path} is a {label(trained)} checkpoint, not a {label(wanted)} "
                      f"one; its row is labelled '{row}' anyway")
    return gen


def _steps(steps):
    """``steps`` checked: an int >= 1, or None for ``generate``'s default
    (:data:`~physlab.motion.sampling.DEFAULT_STEPS`), which every row then uses."""
    if steps is None:
        from .sampling import DEFAULT_STEPS
        return DEFAULT_STEPS
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps must be None (generate's default) or an integer >= 1 (e.g. "
                         f"50 DDIM steps), got {steps!r}")
    return int(steps)


def _sample(gen, data, conds, controlled, steps, guidance, seed, progress, label,
            options=None, body_constraints=True, foot_lock=True, frequencies=None,
            body_frequencies=None):
    """Generate one clip per window; ``options`` are the guidance options of a controlled
    row (:data:`GUIDED`, :data:`UNGUIDED` or a :data:`GUIDANCE_VARIANTS` value);
    ``body_frequencies`` (None: the generator's default) applies to text-only rows."""
    from tqdm.auto import tqdm

    out, total = [], 0.0
    for i in tqdm(range(len(conds)), desc=label, disable=not progress, leave=False):
        c = conds[i]
        kw = ({**(c if isinstance(c, dict) else c.generator_kwargs()), **(options or UNGUIDED)}
              if controlled else {"body_frequencies": body_frequencies})
        tic = time.perf_counter()
        out.append(gen(data["text"][i], seed=seed + i, guidance_scale=guidance, steps=steps,
                       body_constraints=body_constraints, foot_lock=foot_lock,
                       frequencies=frequencies, **kw))                 # (40, 22, 3)
        total += time.perf_counter() - tic
    return np.stack(out), total / len(conds)


def _text_motion_metrics(evaluator, data, seed):
    """``joints (n, 40, 22, 3) -> dict`` of the evaluator columns for ``data``'s texts (an
    empty dict without an evaluator)."""
    if evaluator is None:
        return lambda x: {}
    keys = (*EVALUATOR_COLUMNS, "r_precision_chance_top3")
    if len(data["joints"]) < MIN_EVALUATOR_WINDOWS:
        warnings.warn(f"the text-motion evaluator's columns (FID, R-precision top-3, ...) need "
                      f">= {MIN_EVALUATOR_WINDOWS} windows, got {len(data['joints'])}: left "
                      f"empty")
        return lambda x: dict.fromkeys(keys, float("nan"))
    from .evaluator import DEFAULT_EVALUATOR, TextMotionEvaluator, evaluate_embeddings

    ev = TextMotionEvaluator.from_checkpoint(DEFAULT_EVALUATOR if evaluator == "default"
                                             else evaluator)
    ref = ev.encode_motion(data["reference_joints"])
    temb = ev.encode_text(data["text"])

    def text_motion(x):
        r = evaluate_embeddings(ref, ev.encode_motion(x), temb, texts=data["text"], seed=seed)
        return {k: float(r[k]) for k in keys}
    return text_motion


def _check_scale(name, value, hint=""):
    """A guidance scale (``guidance``, ``control_guidance``, ``condition_scale``): a finite
    number >= 0, else a ValueError naming it."""
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value) or value < 0):
        raise ValueError(f"{name} must be a finite number >= 0{hint}, got {value!r}")


def evaluate(control, single_controlnet=None, windows=64, steps=None, guidance=None, seed=0,
             out=None, progress=True, data_root=None, body_constraints=True,
             control_guidance=1.0, guidance_variants=False, evaluator="default",
             foot_lock=True, frequencies=None, double_controlnet=None, pose_detail=False,
             takes=TEST_TAKES, condition_scale=1.0, text_model=True, body_frequencies=None):
    """Evaluate a control checkpoint on held-out Bandai-Namco windows (module docstring).

    Keyword names match the CLI flags.

    Parameters
    ----------
    control : path of a control checkpoint (``python -m physlab.motion.train --stage
        control``), or of a base checkpoint (``--stage base``): then only the real and
        text-only rows (a text base measured on the same windows).
    single_controlnet, double_controlnet : None or paths of ``--single-controlnet`` /
        ``--double-controlnet`` control checkpoints (Table 2's ablations).
    windows : int >= 1, held-out windows evaluated.
    steps : None (``generate``'s default, :data:`~physlab.motion.sampling.DEFAULT_STEPS`) or
        int >= 1, DDIM steps.
    guidance : None (the generator's default for text only,
        :attr:`~physlab.motion.sampling.Generator.text_guidance`), a number >= 0 or a pair
        ``(w_high, w_low)`` (:func:`~physlab.motion.conditions.check_guidance`): the text CFG
        scale w (Eq. (14)) of the text-only row.
    control_guidance : float >= 0, the text scale of the controlled rows (the generator's
        default under control, :data:`~physlab.motion.sampling.CONTROL_TEXT_GUIDANCE`).
    condition_scale : float >= 0, w_c of Eq. (14) on the keypose and trajectories in every
        controlled row (:meth:`~physlab.motion.sampling.Generator.__call__`; 1 = the
        networks as they are, the generator's default).
    seed : int, seeds the conditions (``rng``) and the samples (``seed + i``).
    out : None or a folder: writes ``table.md`` and ``rows.json`` there (atomically).
    progress : bool, tqdm bars.
    data_root : None or the Bandai-Namco folder.
    body_constraints : bool, the generator's rigid-bone / floor projection
        (:func:`~physlab.motion.body.constrain_body`); False measures the networks' raw
        output.
    foot_lock : bool, the generator's foot-contact lock
        (:func:`~physlab.motion.body.lock_feet`, part of the body constraints).
    frequencies : None (the generator's defaults) or the DCT frequencies x̂₀ keeps, for
        every row (:meth:`~physlab.motion.sampling.Generator.__call__`).
    body_frequencies : None (:data:`~physlab.motion.sampling.BODY_FREQUENCIES`) or the DCT
        frequencies the text-only row's legs and trunk keep (``Generator.__call__``).
    evaluator : ``"default"`` (the shipped :data:`~physlab.motion.evaluator.
        DEFAULT_EVALUATOR`), a path of a text–motion evaluator checkpoint, or None (no
        FID / R-precision / MM-Dist / Diversity columns).
    guidance_variants : bool, add the rows of :data:`GUIDANCE_VARIANTS` for the
        ``--control`` checkpoint (Table A3's analogue: per-step guidance through the network,
        first-order and L-BFGS; ~5-10 s per clip on one thread).
    pose_detail : bool, add :func:`pose_breakdown` as ``"pose_breakdown"`` to the text-only
        row and each networks-only row (:func:`format_pose_breakdown` prints them).
    takes : the takes whose windows are evaluated (:func:`held_out_windows`; default the
        held-out take).
    text_model : bool, sample the text-only row with the checkpoint's attached text model
        when it has one (:func:`~physlab.motion.checkpoint.attach_text_model`); False: with
        the control model's base, as Sketch2Anim does.

    Returns
    -------
    dict ``{row name: {column key: float, "n_clips": int}}`` in :data:`ROW_NAMES` order;
    column keys are those of :data:`COLUMNS` (m for the errors, s for the time) and, with an
    evaluator, of :data:`EVALUATOR_COLUMNS` plus ``r_precision_chance_top3``.
    """
    n = _check_windows(windows)
    steps = _steps(steps)
    guidance = None if guidance is None else check_guidance(guidance, "guidance")
    main_gen = _load(control, "--control", need_control=False, text_model=text_model)
    guidance = main_gen.text_guidance if guidance is None else guidance
    gens = {"keypose + trajectory": main_gen} if main_gen.has_control else {}
    if not gens and (single_controlnet is not None or double_controlnet is not None
                     or guidance_variants or condition_scale != 1.0):
        raise ValueError(f"--control {control} is a base (text-only) checkpoint: it has only "
                         f"the text-only row; drop --single-controlnet / --double-controlnet / "
                         f"--guidance-variants / --condition-scale, or give a control "
                         f"checkpoint")
    for flag, path in (("--single-controlnet", single_controlnet),
                       ("--double-controlnet", double_controlnet)):
        if path is not None:
            gens[VARIANTS[flag][0]] = _load(path, flag)

    takes = _check_takes(takes)
    data = held_out_windows(n, data_root=data_root, takes=takes)
    conds = eval_conditions(data["joints"], seed=seed)
    if not isinstance(body_constraints, (bool, np.bool_)):
        raise TypeError(f"body_constraints must be True or False, got {body_constraints!r}")
    if not isinstance(foot_lock, (bool, np.bool_)):
        raise TypeError(f"foot_lock must be True or False, got {foot_lock!r}")
    _check_scale("control_guidance", control_guidance)
    _check_scale("condition_scale", condition_scale,
                 " (w_c of Eq. (14); 1 = the networks as they are)")
    kw = {"steps": int(steps), "seed": int(seed), "progress": progress,
          "body_constraints": bool(body_constraints), "foot_lock": bool(foot_lock),
          "frequencies": frequencies}
    text_motion = _text_motion_metrics(evaluator, data, seed)

    def metrics(x, s=0.0):
        return {**clip_metrics(x, conds, s), **text_motion(x)}

    rows = {"real clips": metrics(data["joints"])}
    x, s = _sample(main_gen, data, conds, False, label="text only",
                   body_frequencies=body_frequencies,
                   guidance=guidance, **kw)
    rows["text only"] = metrics(x, s)
    if not isinstance(pose_detail, (bool, np.bool_)):
        raise TypeError(f"pose_detail must be True or False, got {pose_detail!r}")
    if pose_detail:
        rows["text only"]["pose_breakdown"] = pose_breakdown(x, conds, data["joints"])
    if not isinstance(guidance_variants, (bool, np.bool_)):
        raise TypeError(f"guidance_variants must be True or False, got {guidance_variants!r}")
    for name, gen in gens.items():
        variants = {"": UNGUIDED, " + guidance": GUIDED}
        if guidance_variants and name == "keypose + trajectory":
            variants.update({" " + k: v for k, v in GUIDANCE_VARIANTS.items()})
        for suffix, options in variants.items():
            label = name + suffix
            x, s = _sample(gen, data, conds, True, label=label,
                           options={**options, "condition_scale": float(condition_scale)},
                           guidance=float(control_guidance), **kw)
            rows[label] = metrics(x, s)
            if pose_detail and not suffix:
                rows[label]["pose_breakdown"] = pose_breakdown(x, conds, data["joints"])

    if out is not None:
        out = Path(out)
        config = {"control": str(control), "single_controlnet": None if single_controlnet
                  is None else str(single_controlnet), "double_controlnet": None
                  if double_controlnet is None else str(double_controlnet),
                  "windows": len(conds),
                  "windows_available": data["n_available"], "steps": int(steps),
                  "guidance": guidance, "control_guidance": float(control_guidance),
                  "condition_scale": float(condition_scale),
                  "seed": int(seed), "min_t_r": MIN_T_R,
                  "test_takes": list(takes), "body_constraints": bool(body_constraints),
                  "foot_lock": bool(foot_lock), "frequencies": frequencies,
                  "body_frequencies": body_frequencies,
                  "guidance_variants": bool(guidance_variants),
                  "pose_detail": bool(pose_detail),
                  "evaluator": None if evaluator is None else str(evaluator),
                  "text_model": main_gen.text_model is not None, "stage": main_gen.stage,
                  "fid_reference_windows": len(data["reference_joints"])}
        detail = format_pose_breakdown(rows)
        atomic_write_text(out / "table.md", format_table(rows, takes) + "\n"
                          + ("\n" + detail + "\n" if detail else ""))
        atomic_write_text(out / "rows.json", json.dumps(
            {"rows": rows, "config": config, "attribution": BANDAI_NAMCO_ATTRIBUTION},
            indent=1))
    return rows


def format_table(rows, takes=TEST_TAKES):
    """Markdown table of :func:`evaluate`'s rows (errors in m, time in s; one column per key
    of :data:`COLUMNS` that the rows have) with the data attribution line; ``takes`` as
    evaluated (named under the table)."""
    names = {**COLUMNS, **EVALUATOR_COLUMNS}
    keys = [k for k in names if rows and all(k in r for r in rows.values())]
    head = ["method", *(names[k] for k in keys)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, r in rows.items():
        cells = ["—" if (k == "seconds_per_clip" and name == "real clips")
                 or not np.isfinite(r[k]) else f"{r[k]:.3f}" if k == "seconds_per_clip"
                 else f"{r[k]:.4f}" for k in keys]
        lines.append("| " + " | ".join([name, *cells]) + " |")
    n = next(iter(rows.values()))["n_clips"] if rows else 0
    lines += ["", (f"{n} {_takes_note(_check_takes(takes))}, one Cross condition "
              f"each; AUJ relative to PJ_GT = {HUMANML3D_GT_PEAK_JERK:.4f} m/frame³; "
              f"edge step ratio / jump: — when no clip has a partial trajectory."),
              *([f"Text–motion evaluator: FID against the other held-out windows, R-precision "
                 f"in batches of 32 with duplicate texts merged (chance top-3 = "
                 f"{next(iter(rows.values()))['r_precision_chance_top3']:.3f})."]
                if "fid" in keys else []),
              f"Data: {BANDAI_NAMCO_ATTRIBUTION}"]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- text adherence

#: Bandai-Namco contents of the text-adherence check; the prompt is ``action_text(content)``
#: (no style adverb, so none of these exact texts was a training text).
ADHERENCE_CONTENTS = ("walk", "run", "walk-back", "walk-left", "bow", "kick",
                      "raise-up-both-hands", "wave-right-hand")
#: Columns of :func:`motion_statistics`.
STATISTICS = ("forward_m", "left_m", "speed_m_s", "hand_above_head_m", "wrist_travel_m")


def motion_statistics(joints, fps=20.0):
    """Simple per-clip numbers an action word predicts, for canonical clips (frame 0 pelvis
    at the origin facing ``+z``).

    Returns a ``(n, 5)`` float array, columns :data:`STATISTICS`: forward travel of the pelvis
    (z of the last frame, m), travel to the left (x, m), mean horizontal pelvis speed along
    its path (m/s), how far the higher wrist rises above the head at its highest
    (m; negative = never above the head), and the wrist travel: the mean per-frame step of
    the busier wrist relative to the pelvis (m/frame; a wave moves it, a walk barely)."""
    x = np.asarray(joints, dtype=float)
    if x.ndim == 3:
        x = x[None]
    if x.ndim != 4 or x.shape[2:] != (22, 3):
        raise ValueError(f"joints must have shape (n, N, 22, 3), got {x.shape}")
    p = x[:, :, 0]                                                         # (n, N, 3) pelvis
    d = p[:, -1] - p[:, 0]
    path = np.linalg.norm(np.diff(p[:, :, [0, 2]], axis=1), axis=-1).sum(1)
    duration = (x.shape[1] - 1) / float(fps)
    hand = (x[:, :, [20, 21], 1].max(axis=2) - x[:, :, 15, 1]).max(axis=1)
    rel = x[:, :, [20, 21]] - p[:, :, None]                                # (n, N, 2, 3)
    wrist = np.linalg.norm(np.diff(rel, axis=1), axis=-1).mean(axis=1).max(axis=1)
    return np.stack([d[:, 2], d[:, 0], path / duration, hand, wrist], axis=1)


def text_adherence(control, contents=ADHERENCE_CONTENTS, seeds=4, steps=None, guidance=None,
                   progress=True, data_root=None, frequencies=None, text_model=True,
                   body_frequencies=None):
    """Does the text-only generator do what the action word says? (Next to the evaluator's
    R-precision, this says *what* differs: travel, speed, hand height.)

    For each content, ``seeds`` text-only clips of ``action_text(content)`` are compared with
    the windows of all Bandai-Namco clips of that content (both takes: the reference says what
    the action looks like; the held-out take lacks some actions) through
    :func:`motion_statistics`; ``guidance`` (None: the generator's
    :attr:`~physlab.motion.sampling.Generator.text_guidance`), ``frequencies`` and
    ``body_frequencies`` as :meth:`Generator.__call__` (None: its text-only defaults);
    ``text_model`` as :func:`evaluate`.
    Recognition: each generated clip is assigned the content whose mean real statistics are
    nearest (statistics scaled by their spread over the real windows); ``accuracy`` is the
    fraction assigned to the content asked for (chance ``1 / len(contents)``).

    Returns
    -------
    dict: ``per_content`` {content: {"text", "n_real", "real": {stat: mean},
    "generated": {stat: mean}, "recognised_as": list of contents}}, ``accuracy`` float,
    ``chance`` float, ``seeds``, ``steps``, ``guidance``, ``quality`` {"real", "generated":
    {"auj", "pj", "skating"}} (:func:`~physlab.motion.metrics.jerk` with reference 0 and
    foot skating over the real windows of the contents and over every generated clip).
    """
    from tqdm.auto import tqdm

    steps = _steps(steps)

    contents = tuple(contents)
    unknown = [c for c in contents if c not in ACTION_PHRASES]
    if not contents or unknown:
        raise ValueError(f"contents must be a non-empty subset of {sorted(ACTION_PHRASES)}; "
                         f"unknown: {unknown}")
    if isinstance(seeds, bool) or not isinstance(seeds, (int, np.integer)) or seeds < 1:
        raise ValueError(f"seeds must be an integer >= 1, got {seeds!r}")
    guidance = None if guidance is None else check_guidance(guidance, "guidance")
    gen = _load(control, "--control", need_control=False,         # text only: a base will do
                text_model=text_model)
    guidance = gen.text_guidance if guidance is None else guidance
    win = make_windows(load_clips(data_root), length=WINDOW_LENGTH, stride=WINDOW_STRIDE)
    real_stats = motion_statistics(win.joints, fps=win.fps)               # (M, 4)
    labels = np.asarray(win.content)
    missing = [c for c in contents if not np.any(labels == c)]
    if missing:
        raise ValueError(f"no Bandai-Namco windows of {missing}")
    means = np.stack([real_stats[labels == c].mean(0) for c in contents])  # (C, 4)
    scale = real_stats.std(0) + 1e-9
    per, hits, total, made = {}, 0, 0, []
    for k, c in enumerate(tqdm(contents, desc="text adherence", disable=not progress)):
        text = action_text(c)
        clips = np.stack([gen(text, seed=s, steps=steps, guidance_scale=guidance,
                              frequencies=frequencies, body_frequencies=body_frequencies)
                          for s in range(seeds)])
        made.append(clips)
        g = motion_statistics(clips)                                       # (S, 4)
        nearest = np.argmin((((g[:, None] - means[None]) / scale) ** 2).sum(-1), axis=1)
        rec = [contents[j] for j in nearest]
        hits += sum(r == c for r in rec)
        total += len(rec)
        per[c] = {"text": text, "n_real": int(np.sum(labels == c)),
                  "real": dict(zip(STATISTICS, means[k].tolist())),
                  "generated": dict(zip(STATISTICS, g.mean(0).tolist())),
                  "recognised_as": rec}
    real = win.joints[np.isin(labels, contents)]
    made = np.concatenate(made)

    def quality(J):                                    # AUJ, PJ (m/frame³), foot skating
        auj, pj = jerk(J)
        return {"auj": auj, "pj": pj, "skating": float(np.mean(foot_skating_ratio(J)))}

    return {"per_content": per, "accuracy": hits / total, "chance": 1.0 / len(contents),
            "seeds": int(seeds), "steps": int(steps), "guidance": guidance,
            "quality": {"real": quality(real), "generated": quality(made)}}


#: Noise levels of :func:`detail_kept` (0: the clean clip, one network call — does the
#: network hand back what it is given?; None: pure noise, as in sampling).
DETAIL_LEVELS = (0, 20, 150, 300, 600, 900, None)


def detail_kept(control, content="wave-right-hand", levels=DETAIL_LEVELS, windows=8,
                statistic="wrist_travel_m", steps=40, guidance=2.5, seed=0, data_root=None,
                progress=True):
    """How much of a real motion's detail the text-only denoiser keeps when it starts from
    noise level t: held-out (take 002) windows of ``content`` are noised to each level,
    denoised back by DDIM with the action's text (all its clips when take 002 has none) (:meth:`Generator.denoise_from`), and
    ``statistic`` (a column of :func:`motion_statistics`) is compared with the real windows'.
    A well-fit denoiser keeps the statistic at low levels (the clip is still there) and a
    text-only sample (None) should reach it too; a damped one loses it already at t = 20, or
    even at t = 0, where the clean clip is handed to the network (one DDIM step: its x̂₀).

    Whether the network *reads* the clip, rather than writing the action's typical value over
    it, shows in ``slopes``: the least-squares slope of the denoised windows' statistic on the
    real windows' (:func:`follow_slope`): 1 = hands back each window's value, 0 = ignores it
    (from pure noise it should be about 0).

    Returns dict: ``real`` (mean statistic of the chosen windows), ``levels`` {level or
    "noise": mean statistic after denoising}, ``slopes`` {same keys: :func:`follow_slope`},
    ``content``, ``statistic``, ``windows``, ``held_out`` (False when take 002 has no clip of
    the action and all takes were used).
    """
    from tqdm.auto import tqdm

    if content not in ACTION_PHRASES:
        raise ValueError(f"content must be one of {sorted(ACTION_PHRASES)}, got {content!r}")
    if statistic not in STATISTICS:
        raise ValueError(f"statistic must be one of {STATISTICS}, got {statistic!r}")
    if isinstance(windows, bool) or not isinstance(windows, (int, np.integer)) or windows < 1:
        raise ValueError(f"windows must be an integer >= 1, got {windows!r}")
    gen = _load(control, "--control", need_control=False)
    clips = load_clips(data_root, contents=[content])
    test = [c for c in clips if c.take in TEST_TAKES]      # held out; else (an action the take
    win = make_windows(test or clips, length=WINDOW_LENGTH,  # lacks) every clip of it
                       stride=WINDOW_STRIDE)
    rng = np.random.default_rng(seed)
    J = win.joints[rng.choice(len(win.joints), min(windows, len(win.joints)), replace=False)]
    col = STATISTICS.index(statistic)
    text = action_text(content)
    real = motion_statistics(J)[:, col]
    out, slopes = {}, {}
    for level in tqdm(list(levels), desc="detail kept", disable=not progress):
        got = [gen.denoise_from(j, level, text, noise_seed=seed + i, steps=steps,
                                guidance_scale=guidance) for i, j in enumerate(J)]
        key = "noise" if level is None else int(level)
        g = motion_statistics(np.stack(got))[:, col]
        out[key], slopes[key] = float(g.mean()), follow_slope(real, g)
    return {"real": float(real.mean()), "levels": out, "slopes": slopes,
            "content": content, "statistic": statistic, "windows": len(J),
            "held_out": bool(test)}


def follow_slope(real, got):
    """Least-squares slope of ``got`` on ``real`` (two (n,) arrays of a per-window statistic):
    ``cov(real, got) / var(real)``. 1 when ``got`` follows ``real`` one to one (plus any
    offset), 0 when it does not depend on it, 0.5 when it keeps half of each window's
    deviation from the mean. NaN when ``real`` does not vary (fewer than 2 windows)."""
    r, g = np.asarray(real, dtype=float), np.asarray(got, dtype=float)
    if r.ndim != 1 or r.shape != g.shape:
        raise ValueError(f"real and got must be 1-D arrays of one length, got shapes {r.shape} "
                         f"and {g.shape}")
    var = np.var(r)
    if len(r) < 2 or not var > 1e-12 * max(1.0, float(np.mean(r ** 2))):
        return float("nan")
    return float(np.mean((r - r.mean()) * (g - g.mean())) / var)


def format_detail(res):
    """Markdown table of :func:`detail_kept`: the mean statistic per level, and the slope on
    the real windows' when the result has ``slopes``."""
    keys = list(res["levels"])
    head = ["real", *[f"from t = {k}" if k != "noise" else "from noise" for k in keys]]
    vals = [res["real"], *res["levels"].values()]
    which = ("held-out windows" if res.get("held_out", True)
             else "windows (all takes: take 002 has none)")
    lines = [f"{res['statistic']} of {res['windows']} '{res['content']}' {which}, "
             f"denoised back (text only):", "",
             "| | " + " | ".join(head) + " |", "|" + "---|" * (len(head) + 1),
             "| mean | " + " | ".join(f"{v:.4f}" for v in vals) + " |"]
    if "slopes" in res:                 # how much of each window's own value comes back
        lines.append("| slope on real | 1 | " + " | ".join(
            "—" if not np.isfinite(v) else f"{v:.2f}" for v in res["slopes"].values()) + " |")
    return "\n".join(lines)


def _ratio(gen, real, signed):
    """``gen / real`` as a percentage (``signed``: ``gen / real − 1``, "+24 %"); "—" if
    ``real`` is 0 or either is not finite."""
    if not (np.isfinite(gen) and np.isfinite(real)) or real == 0:
        return "—"
    r = 100.0 * (gen / real - (1.0 if signed else 0.0))
    return f"{r:+.0f} %" if signed else f"{r:.0f} %"


def format_adherence(res):
    """Markdown table of :func:`text_adherence` (real mean / generated mean per statistic),
    with the two ratios issue 12's bounds are written in: the mean pelvis speed against the
    real one (``gen / real − 1``; bound ±30 %) and the wrist travel as a fraction of the real
    one (bound ≥ 50 % for the wave and raised hands), computed from the unrounded means."""
    head = ["action text", "real windows", "forward (m) real / gen", "left (m) real / gen",
            "speed (m/s) real / gen", "hand above head (m) real / gen",
            "wrist travel (m/frame) real / gen", "speed gen vs real",
            "wrist travel gen / real", "recognised"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c, r in res["per_content"].items():
        real, gen = r["real"], r["generated"]
        cells = [f"{real[k]:+.2f} / {gen[k]:+.2f}" for k in STATISTICS[:-1]]
        cells.append(f"{real[STATISTICS[-1]]:.3f} / {gen[STATISTICS[-1]]:.3f}")
        cells += [_ratio(gen["speed_m_s"], real["speed_m_s"], signed=True),
                  _ratio(gen["wrist_travel_m"], real["wrist_travel_m"], signed=False)]
        ok = sum(x == c for x in r["recognised_as"])
        lines.append("| " + " | ".join([r["text"], str(r["n_real"]), *cells,
                                        f"{ok}/{len(r['recognised_as'])}"]) + " |")
    lines += ["", f"Text only, {res['seeds']} seeds per text, {res['steps']} DDIM steps, "
              f"w = {format_guidance(res['guidance'])}. Recognition accuracy (nearest real "
              f"action mean): "
              f"{res['accuracy']:.2f} (chance {res['chance']:.2f})."]
    if "quality" in res:
        r, g = res["quality"]["real"], res["quality"]["generated"]
        lines.append(f"Jerk (plain area / peak of the mean jerk curve, m/frame³) real "
                     f"{r['auj']:.2f} / {r['pj']:.3f}, generated {g['auj']:.2f} / "
                     f"{g['pj']:.3f}; foot skating real {r['skating']:.3f}, generated "
                     f"{g['skating']:.3f}.")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- 2D sketches

#: Rows and columns of :func:`evaluate_sketch` (Table 1's 2D and 3D control errors).
SKETCH_COLUMNS = {
    "trajectory_error_2d": "traj. err.-2D ↓",
    "keypose_mpjpe_2d": "keypose MPJPE-2D ↓",
    "trajectory_error_3d": "traj. err.-3D (m) ↓",
    "keypose_pose_3d": "keypose pose err. (m) ↓",
    "foot_skating": "foot skating ↓",
    "auj": "AUJ ↓",
    "seconds_per_clip": "s / clip",
}


def sketch_metrics(motions, conds, cameras, seconds=0.0):
    """Errors of clips against their conditions as drawn in ``cameras``: the average 2D
    trajectory error (normalised image units, over all controlled frames and joints, as the
    3D one) and the 2D keypose MPJPE (root-relative projected pose at the key frame, mean
    over joints and clips), next to the 3D errors, skating and jerk of :func:`clip_metrics`."""
    x = np.asarray(motions, dtype=float)
    p = np.stack([cam.project(xi) for xi, cam in zip(x, cameras)])            # (n, N, 22, 2)
    masks = np.stack([c.mask for c in conds])
    traj = (trajectory_error(p, np.stack([cam.project(c.trajectory) for c, cam
                                          in zip(conds, cameras)]), TRAJECTORY_JOINTS, masks)
            if masks.any() else 0.0)
    key = [mpjpe(pi[c.key_frame], cam.project(c.keypose), root_relative=True)
           for pi, c, cam in zip(p, conds, cameras)]
    row = clip_metrics(x, conds, seconds)
    return {"trajectory_error_2d": traj, "keypose_mpjpe_2d": float(np.mean(key)),
            **{k: row[k] for k in SKETCH_COLUMNS if k in row}, "n_clips": row["n_clips"]}


#: Protocols of the 2D table (Sketch2Anim Table 1): ``cross`` — each window a random subset
#: of the six trajectory joints (:func:`eval_conditions`); ``average`` — one joint per window,
#: the six in turn (the table reports the mean over joints).
SKETCH_PROTOCOLS = ("cross", "average")


def sketch_conditions(joints, protocol="cross", seed=0):
    """The held-out conditions of the 2D table (:data:`SKETCH_PROTOCOLS`)."""
    if protocol not in SKETCH_PROTOCOLS:
        raise ValueError(f"protocol must be one of {SKETCH_PROTOCOLS}, got {protocol!r}")
    if protocol == "cross":
        return eval_conditions(joints, seed=seed)
    rng = np.random.default_rng(seed)
    out = []
    for i, w in enumerate(joints):
        t_r = int(rng.integers(MIN_T_R, len(w) + 1))
        out.append(condition_from_window(w, t_r=t_r, keypose_at="first" if i % 2 == 0
                                         else "last",
                                         joints=(TRAJECTORY_JOINTS[i % len(TRAJECTORY_JOINTS)],)))
    return out


def draw_conditions(conds, seed=0, noise=0.0):
    """Each condition drawn as a user would (Table 1's setting): a random storyboard view per
    condition (:func:`~physlab.motion.camera.random_camera`, supp. B ranges, seeded by
    ``seed + 1``) and the projected keypose / trajectories (:func:`~physlab.motion.camera.
    sketch_kwargs`, joint noise ``noise``). Returns ``(cameras, sketches)``: lists of
    :class:`~physlab.motion.camera.Camera` and of ``generate`` keywords."""
    from .camera import random_camera, sketch_kwargs

    rng = np.random.default_rng(seed + 1)
    cams = [random_camera(rng) for _ in conds]
    sketches = [sketch_kwargs(c, cam, rng=np.random.default_rng(seed + 2 + i), noise=noise)
                for i, (c, cam) in enumerate(zip(conds, cams))]
    return cams, sketches


def evaluate_sketch(control, windows=64, steps=None, seed=0, noise=0.0, progress=True,
                    data_root=None, out=None, protocol="cross", lifter=None, direct_2d=None,
                    retrieval=False, evaluator=None, guidance_only=False,
                    guidance_variants=False):
    """The 2D path on held-out windows (Sketch2Anim Table 1's setting): each window's
    condition (:func:`sketch_conditions`) is projected in a random storyboard view
    (:func:`~physlab.motion.camera.random_camera`, supp. B ranges) and given as a sketch
    (:func:`~physlab.motion.camera.sketch_kwargs`, optional joint noise).

    Rows: real clips, text only; optional baselines — ``retrieval`` (:class:`~physlab.
    motion.baselines.MotionRetrieval` over the training windows), ``lifter`` (path of the
    lift-and-control lifter: networks only and + guidance), ``direct_2d`` (path of a
    ``--direct-2d`` control checkpoint: networks only and + guidance); then ``control``:
    with its 2D encoders (stage ``align``) networks only and + guidance, and (``guidance_only``
    or no encoders) the 3D generator driven by the 2D guidance alone; and the same condition
    in 3D through the networks, without guidance (what the aligned 2D encoders can at best
    reach: they stand in for the 3D encoders) and with it, for reference. ``guidance_variants`` adds Table A3's
    rows for the 2D encoders: :data:`GUIDANCE_VARIANTS` (per-step guidance through the
    network, first-order and L-BFGS; ~5 s per clip).

    Returns ``{row: metrics}`` (:data:`SKETCH_COLUMNS`, plus the evaluator's columns when
    ``evaluator`` is given: ``"default"`` or a path)."""
    from .sampling import CONTROL_TEXT_GUIDANCE

    n = _check_windows(windows)
    gen = _load(control, "--control")
    data = held_out_windows(n, data_root=data_root)
    conds = sketch_conditions(data["joints"], protocol, seed=seed)
    cams, sketches = draw_conditions(conds, seed=seed, noise=noise)
    kw = {"steps": _steps(steps), "seed": int(seed), "progress": progress}
    text_motion = _text_motion_metrics(evaluator, data, seed)

    def metrics(x, s=0.0):
        return {**sketch_metrics(x, conds, cams, s), **text_motion(x)}

    rows = {"real clips": metrics(data["joints"])}
    x, s = _sample(gen, data, conds, False, label="text only", guidance=None, **kw)
    rows["text only"] = metrics(x, s)
    if retrieval:
        from .baselines import MotionRetrieval

        db = (retrieval if isinstance(retrieval, MotionRetrieval)
              else MotionRetrieval.from_training_data(data_root))
        tic = time.perf_counter()
        x = np.stack([db(t, **k) for t, k in zip(data["text"], sketches)])
        rows["retrieval"] = metrics(x, (time.perf_counter() - tic) / len(x))
    if lifter is not None:
        from .baselines import lift, load_lifter

        net = load_lifter(lifter)
        lifted = []
        for k in sketches:
            k3, t3 = lift(net, **k)
            lifted.append({"keypose_3d": k3, "trajectories_3d": t3,
                           "keypose_at": k["keypose_at"]})
        for suffix, options in (("", UNGUIDED), (" + guidance", GUIDED)):
            x, s = _sample(gen, data, lifted, True, label="lift-and-control" + suffix,
                           options=options, guidance=CONTROL_TEXT_GUIDANCE, **kw)
            rows["lift-and-control" + suffix] = metrics(x, s)
    variants = []
    if direct_2d is not None:
        variants.append(("direct 2D", _load(direct_2d, "--direct-2d")))
    if gen.has_sketch_encoders:
        variants.append(("physlab (2D encoders)", gen))
    for name, g in variants:
        if not g.has_sketch_encoders:
            raise ValueError(f"{name}: {g.path} has no 2D encoders")
        options_of = {"": UNGUIDED, " + guidance": GUIDED}
        if guidance_variants and g is gen:
            options_of.update({" " + k: v for k, v in GUIDANCE_VARIANTS.items()})
        for suffix, options in options_of.items():
            x, s = _sample(g, data, sketches, True, label=name + suffix, options=options,
                           guidance=CONTROL_TEXT_GUIDANCE, **kw)
            rows[name + suffix] = metrics(x, s)
    if guidance_only or not gen.has_sketch_encoders:
        x, s = _sample(gen, data, [{**k, "sketch_encoders": False} for k in sketches], True,
                       label="2D guidance only", options=GUIDED,
                       guidance=CONTROL_TEXT_GUIDANCE, **kw)
        rows["3D generator, 2D guidance only"] = metrics(x, s)
    for suffix, options in ((" only", UNGUIDED), (" + guidance", GUIDED)):
        x, s = _sample(gen, data, conds, True, label="3D conditions" + suffix, options=options,
                       guidance=CONTROL_TEXT_GUIDANCE, **kw)
        rows["3D conditions, networks" + suffix] = metrics(x, s)
    if out is not None:
        atomic_write_text(Path(out) / f"sketch_{protocol}.md",
                          format_sketch_table(rows, noise, protocol) + "\n")
        atomic_write_text(Path(out) / f"sketch_{protocol}.json", json.dumps(
            {"rows": rows, "protocol": protocol, "noise": noise, "windows": len(conds),
             "seed": int(seed), "attribution": BANDAI_NAMCO_ATTRIBUTION}, indent=1))
    return rows


def evaluate_alignment_ablation(variants, windows=64, steps=None, seed=0, noise=0.0,
                                progress=True, data_root=None, protocol="cross",
                                evaluator=None, out=None):
    """Table A2's analogue: the networks alone (no inference guidance, as the paper's
    ablation) of each aligned checkpoint in ``variants`` ``{row name: path}`` (e.g. trained
    with ``--lambda-recon 0``), on the held-out windows drawn as in :func:`evaluate_sketch`
    (same conditions, views and noise for every row). Returns ``{row: metrics}``."""
    from .sampling import CONTROL_TEXT_GUIDANCE

    if not variants:
        raise ValueError("variants must name at least one aligned checkpoint, "
                         "{name: path}")
    n = _check_windows(windows)
    gens = {name: _load(path, f"--ablation {name}") for name, path in variants.items()}
    for name, g in gens.items():
        if not g.has_sketch_encoders:
            raise ValueError(f"--ablation {name}: {g.path} has no 2D encoders (train it with "
                             f"--stage align)")
    data = held_out_windows(n, data_root=data_root)
    conds = sketch_conditions(data["joints"], protocol, seed=seed)
    cams, sketches = draw_conditions(conds, seed=seed, noise=noise)
    text_motion = _text_motion_metrics(evaluator, data, seed)
    rows = {}
    for name, g in gens.items():
        x, s = _sample(g, data, sketches, True, label=name, options=UNGUIDED,
                       guidance=CONTROL_TEXT_GUIDANCE, steps=_steps(steps), seed=int(seed),
                       progress=progress)
        rows[name] = {**sketch_metrics(x, conds, cams, s), **text_motion(x)}
    if out is not None:
        atomic_write_text(Path(out) / f"ablation_{protocol}.md",
                          format_sketch_table(rows, noise, protocol) + "\n")
    return rows


def format_sketch_table(rows, noise=0.0, protocol="cross"):
    """Markdown table of :func:`evaluate_sketch`."""
    names = {**SKETCH_COLUMNS, **EVALUATOR_COLUMNS}
    keys = [k for k in names if rows and all(k in r for r in rows.values())]
    head = ["method", *(names[k] for k in keys)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, r in rows.items():
        cells = ["—" if k == "seconds_per_clip" and name == "real clips"
                 else f"{r[k]:.3f}" if k == "seconds_per_clip" else f"{r[k]:.4f}"
                 for k in keys]
        lines.append("| " + " | ".join([name, *cells]) + " |")
    n = next(iter(rows.values()))["n_clips"]
    lines += ["", f"{n} held-out windows, {protocol} protocol, each condition drawn in a random "
              f"view (pitch 0–30°, yaw ±45°, scale 0.8–1.2; joint noise σ = {noise:g}); 2D "
              f"errors in normalised image units (1 = 1 m at scale 1)."]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- CLI


# ----------------------------------------------------------------------------- blending
# Sketch2Anim Table A4 analogue: how well each blending method fills a masked transition of
# real motion (supp. D, "Performance evaluation").
#
# Data: the held-out take's 40-frame windows (:func:`held_out_windows`) that change the most between their first and last quarter — the paper
# selects HumanML3D samples whose text names two actions; the Bandai-Namco clips are one
# action each, so physlab takes the windows where the motion changes phase (standing →
# walking, arm at rest → raised, walking → turning): the score is the change of mean joint
# speed between frames 0–9 and 30–39 plus the root-relative pose distance between frames 9
# and 30. The middle ``transition`` frames are masked, each method fills them from the
# context on both sides (:func:`~physlab.motion.blend.blend`), and the filled windows are
# compared with the real ones:
#
# * **FID** of the shipped text–motion evaluator (filled windows vs. the other held-out
#   windows; the real masked windows themselves as the sanity row);
# * **AUJ** and **PJ** (:func:`~physlab.motion.metrics.jerk`, FlowMDM's definitions,
#   per-frame units) over the transition and two frames on each side; the real windows' PJ is
#   the target (the paper: "close to GT is better");
# * **MPJPE** to the real frames of the transition (m), the largest **step ratio** over the
#   frames a method changed (:func:`~physlab.motion.blend.junction_step_ratio` on
#   :attr:`~physlab.motion.blend.BlendResult.window`: the gap, and for ``inversion`` /
#   ``inpaint`` the context frames they cross-fade too; the real windows' value alongside),
#   bone-length variation and floor penetration of the filled windows.
#
# ``python -m physlab.motion.evaluate --blending`` prints the table.

#: Frames on each side of the transition included in the jerk statistics.
JERK_MARGIN = 2


def phase_change_score(joints, context=10):
    """How much each window changes between its first and last ``context`` frames:
    ``|mean joint speed(first) − mean joint speed(last)|`` (m/frame) ``+`` the mean
    root-relative joint distance between frames ``context − 1`` and ``T − context`` (m).

    joints : (B, T, 22, 3). Returns (B,) float."""
    x = np.asarray(joints, dtype=float)
    if x.ndim != 4 or x.shape[2:] != (22, 3):
        raise ValueError(f"joints must be a (B, T, 22, 3) batch of windows, got {x.shape}")
    if isinstance(context, bool) or not isinstance(context, (int, np.integer)) \
            or not 2 <= context <= x.shape[1] // 2:
        raise ValueError(f"context must be an integer in 2..T/2 = {x.shape[1] // 2}, got "
                         f"{context!r}")
    v = np.linalg.norm(np.diff(x, axis=1), axis=-1).mean(-1)                # (B, T-1)
    speed = np.abs(v[:, :context - 1].mean(1) - v[:, -(context - 1):].mean(1))
    rel = x - x[:, :, :1]
    pose = np.linalg.norm(rel[:, context - 1] - rel[:, -context], axis=-1).mean(-1)
    return speed + pose


def blending_windows(windows=32, pool=256, data_root=None, context=10):
    """The ``windows`` held-out windows with the largest :func:`phase_change_score` among
    ``pool`` evenly spaced ones; the rest of the pool is FID's reference. Returns dict
    ``joints`` (n, 40, 22, 3), ``text`` list, ``reference_joints``, ``score`` (n,)."""
    if isinstance(windows, bool) or not isinstance(windows, (int, np.integer)) or windows < 2:
        raise ValueError(f"windows must be an integer >= 2, got {windows!r}")
    data = held_out_windows(max(int(pool), int(windows)), data_root=data_root)
    x = np.concatenate([data["joints"], data["reference_joints"]])
    texts = list(data["text"]) + [""] * len(data["reference_joints"])
    n_sel = len(data["joints"])
    s = phase_change_score(x[:n_sel], context)
    order = np.argsort(-s)[:int(windows)]
    rest = np.setdiff1d(np.arange(len(x)), order)
    return {"joints": x[order], "text": [texts[i] for i in order],
            "reference_joints": x[rest], "score": s[order]}


#: Rows of :func:`evaluate_blending`: name -> keywords of :func:`~physlab.motion.blend.blend`.
BLEND_ROWS = {"linear": {"method": "linear"}, "slerp": {"method": "slerp"},
              "squad": {"method": "squad"}, "inpaint (DoubleTake-like)": {"method": "inpaint"},
              "inversion": {"method": "inversion"},
              "inversion, z_t guidance": {"method": "inversion", "guidance_space": "network"}}


def evaluate_blending(windows=32, transition=TRANSITION, methods=tuple(BLEND_ROWS), seed=0,
                      data_root=None, evaluator="default", generator=None, progress=True,
                      blend_options=None):
    """Table A4 analogue (module docstring); ``methods``: names of :data:`BLEND_ROWS`.
    Returns ``{row_name: {metric: value}}`` with a
    ``"real"`` row first."""
    from .sampling import _progress

    if isinstance(methods, str):
        methods = (methods,)
    bad = [m for m in methods if m not in BLEND_ROWS]
    if bad:
        raise ValueError(f"methods must come from {tuple(BLEND_ROWS)}, got {bad}")
    data = blending_windows(windows, data_root=data_root)
    gt = data["joints"]                                                     # (n, 40, 22, 3)
    n, T = gt.shape[:2]
    l = int(transition)
    if not 1 <= l <= T - 2 * (JERK_MARGIN + 1):
        raise ValueError(f"transition must be in 1..{T - 2 * (JERK_MARGIN + 1)} (a {T}-frame "
                         f"window keeps {JERK_MARGIN + 1} context frames a side for the jerk), "
                         f"got {transition!r}")
    ca = (T - l) // 2
    lo, hi = ca - JERK_MARGIN, ca + l + JERK_MARGIN
    text_motion = None
    if evaluator is not None:
        if n < 8:
            warnings.warn("FID needs >= 8 windows: left out")
        else:
            from .evaluator import DEFAULT_EVALUATOR, TextMotionEvaluator, fid

            ev = TextMotionEvaluator.from_checkpoint(DEFAULT_EVALUATOR if evaluator == "default"
                                                     else evaluator)
            ref = ev.encode_motion(data["reference_joints"])

            def text_motion(x):
                return fid(ref, ev.encode_motion(x))

    def row(filled, seconds, changed=None):
        """``changed``: per window, the slice the method changed (default: the gap)."""
        changed = changed or [slice(ca, ca + l)] * len(filled)
        auj, pj = jerk(filled[:, lo:hi])
        r = {"FID": text_motion(filled) if text_motion else float("nan"),
             "AUJ": auj, "PJ": pj,
             "MPJPE": float(np.mean([mpjpe(f[ca:ca + l], g[ca:ca + l])
                                     for f, g in zip(filled, gt)])),
             # the context frames a method changed (inversion cross-fades them; 0 otherwise)
             "context": float(np.mean(np.linalg.norm(
                 np.concatenate([filled[:, :ca], filled[:, ca + l:]], axis=1)
                 - np.concatenate([gt[:, :ca], gt[:, ca + l:]], axis=1), axis=-1))),
             "step_ratio": float(np.max([junction_step_ratio(
                 f, slice(max(w.start, 1), min(w.stop, T - 1)), [g[:ca], g[ca + l:]])
                 for f, g, w in zip(filled, gt, changed)])),
             "bones": float(np.max(bone_length_variation(filled))),
             "floor": float(np.mean(floor_penetration(filled))),
             "seconds": seconds}
        return r

    rows = {"real": row(gt, 0.0)}
    for method in methods:
        out, changed, t0 = [], [], time.perf_counter()
        for i in _progress(range(n), progress, method):
            res = blend(gt[i, :ca], gt[i, ca + l:], transition=l,
                        actions=(data["text"][i], data["text"][i]), generator=generator,
                        seed=seed + i, **{**BLEND_ROWS[method], **(blend_options or {})})
            out.append(res.joints)
            changed.append(res.window)
        rows[method] = row(np.stack(out), (time.perf_counter() - t0) / n, changed)
    return rows


def format_blending_table(rows, transition=TRANSITION):
    """Markdown table of :func:`evaluate_blending`."""
    head = ("| method | FID ↓ | AUJ ↓ | PJ (real = {pj:.4f}) | MPJPE m ↓ | context drift m | "
            "max step ratio | bone var m | floor % | s / transition |"
            ).format(pj=rows["real"]["PJ"])
    lines = [f"Blending a masked {transition}-frame transition (Table A4 analogue, held-out "
             f"windows that change phase)", "", head, "|" + " --- |" * 10]
    for name, r in rows.items():
        lines.append(f"| {name} | {r['FID']:.3f} | {r['AUJ']:.3f} | {r['PJ']:.4f} | "
                     f"{r['MPJPE']:.3f} | {r['context']:.3f} | {r['step_ratio']:.2f} | "
                     f"{r['bones']:.4f} | {100 * r['floor']:.1f} | {r['seconds']:.2f} |")
    return "\n".join(lines)


def _parser():
    from physlab._cli import Parser

    p = Parser(
        prog="python -m physlab.motion.evaluate",
        description="Held-out Bandai-Namco evaluation of the motion generator (Sketch2Anim "
                    "Table 2 analogue): real clips, text only, keypose + trajectory, single "
                    "ControlNet; foot skating, MPJPE-3D, trajectory error, AUJ, PJ, s/clip.",
        epilog="examples:\n"
               "  %(prog)s --control data/motion/sketch2anim_control.pt --windows 16\n"
               "  %(prog)s --control runs/control.pt --single-controlnet runs/single.pt "
               "--out runs/eval\n"
               "  %(prog)s --control runs/smoke_control.pt --windows 2 --steps 2    # seconds")
    p.add_argument("--control", default=None,
                   help="control checkpoint (train --stage control), or a base checkpoint "
                        "for the real and text-only rows; required unless --blending")
    p.add_argument("--single-controlnet", default=None,
                   help="optional single-ControlNet control checkpoint (Table 2 ablation)")
    p.add_argument("--double-controlnet", default=None,
                   help="optional double-ControlNet control checkpoint (Table 2 ablation: "
                        "train --stage control --double-controlnet)")
    p.add_argument("--windows", type=int, default=64, help="held-out windows (default 64)")
    p.add_argument("--steps", type=int, default=None,
                   help="DDIM steps (default: generate's, physlab.motion.sampling.DEFAULT_STEPS)")
    p.add_argument("--guidance", type=guidance_argument, default=None,
                   help="text CFG scale of the text-only row and --adherence: W, or HIGH,LOW "
                        "(HIGH at the upper half of the noise levels, LOW below; default: the "
                        "generator's, its text model's own or 2.5)")
    p.add_argument("--control-guidance", type=float, default=1.0,
                   help="text CFG scale of the controlled rows (default 1)")
    p.add_argument("--condition-scale", type=float, default=1.0,
                   help="w_c of Eq. (14) on the keypose and trajectories in the controlled "
                        "rows of the 3D table (default 1: the networks as they are)")
    p.add_argument("--seed", type=int, default=0, help="conditions and sampling seed")
    p.add_argument("--out", type=Path, default=None, help="folder for table.md and rows.json")
    p.add_argument("--data", "--data-root", dest="data_root", default=None,
                   help="folder of BVH clips with a labels.csv in the Bandai-Namco format "
                        "(default: ../shared/data/mocap/bandai_namco); its take-002 clips "
                        "are evaluated")
    p.add_argument("--evaluator", default="default",
                   help="text-motion evaluator checkpoint for FID / R-precision / MM-Dist / "
                        "Diversity (default: the shipped data/motion/text_motion_evaluator.pt)")
    p.add_argument("--no-evaluator", action="store_true",
                   help="leave out the evaluator's columns")
    p.add_argument("--guidance-variants", action="store_true",
                   help="add per-step guidance rows through the network, first-order and "
                        "L-BFGS (Table A3; ~5-10 s per clip)")
    p.add_argument("--take", action="append", default=None, metavar="TAKE",
                   help="evaluate the windows of this take instead of the held-out "
                        f"{', '.join(TEST_TAKES)} (repeatable; e.g. --take 003, a training take, "
                        "shows what the model fits); the 3D table only")
    p.add_argument("--pose-detail", action="store_true",
                   help="also split the keypose pose error of the text-only and networks-only "
                        "rows by clip, key frame, joint group and turn (pose_breakdown)")
    p.add_argument("--adherence", action="store_true",
                   help="also run the text-adherence check of the text-only generator")
    p.add_argument("--adherence-seeds", type=int, default=4,
                   help="clips per action text in the adherence check (default 4)")
    p.add_argument("--detail", default=None, metavar="CONTENT",
                   help="how much of CONTENT's real motion (e.g. wave-right-hand) the text-only "
                        "denoiser keeps from noise levels 0..900 and from pure noise, and how "
                        "closely it follows each window (slope on real)")
    p.add_argument("--detail-windows", type=int, default=8, metavar="N",
                   help="windows --detail denoises back (default 8; more for a steadier slope)")
    p.add_argument("--detail-statistic", default="wrist_travel_m", choices=STATISTICS,
                   help="what --detail measures (default wrist_travel_m; forward_m for walks)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--num-threads", type=int, default=1,
                   help="torch threads (default 1: one clip at a time samples fastest on one "
                        "thread, and beside other jobs more threads spin and slow everything "
                        "down: 15 s instead of 1 s per clip measured here)")
    p.add_argument("--no-body-constraints", action="store_true",
                   help="measure the networks' raw joints (no rigid-bone / floor projection)")
    p.add_argument("--sketch", action="store_true",
                   help="also evaluate the 2D path: each condition drawn in a random view")
    p.add_argument("--sketch-noise", type=float, default=0.0,
                   help="joint noise sigma of the drawn points (supp. B: 0.02)")
    p.add_argument("--protocol", choices=[*SKETCH_PROTOCOLS, "both"], default="cross",
                   help="conditions of the 2D table (default cross)")
    p.add_argument("--retrieval", action="store_true",
                   help="2D table: add the motion-retrieval baseline (training windows)")
    p.add_argument("--lifter", default=None,
                   help="2D table: add lift-and-control with this lifter checkpoint")
    p.add_argument("--direct-2d", default=None,
                   help="2D table: add the direct 2D baseline (train --direct-2d checkpoint)")
    p.add_argument("--guidance-only", action="store_true",
                   help="2D table: add the 3D generator driven by the 2D guidance alone")
    p.add_argument("--ablation", action="append", default=[], metavar="NAME=PATH",
                   help="Table A2: networks-only 2D rows of aligned checkpoints (repeat; "
                        "e.g. 'w/o L_recon=runs/a2/no_recon.pt'); with --sketch")
    p.add_argument("--no-3d", action="store_true",
                   help="skip the 3D table (with --sketch: only the 2D one)")
    p.add_argument("--blending", action="store_true",
                   help="Table A4 analogue: fill a masked transition of held-out phase-change "
                        "windows with each blending method (physlab.motion.evaluate)")
    p.add_argument("--transition", type=int, default=20,
                   help="--blending: masked frames (default 20, Sketch2Anim supp. D)")
    p.add_argument("--no-foot-lock", action="store_true",
                   help="body constraints without the foot-contact lock")
    p.add_argument("--no-text-model", action="store_true",
                   help="text-only clips (text-only row, --adherence) from the control model's "
                        "base, as Sketch2Anim does, even if the checkpoint has a text model")
    p.add_argument("--frequencies", type=int, default=None,
                   help="DCT frequencies x̂₀ keeps in every row and in --adherence (default: "
                        "the generator's, 10; the checkpoint was trained with 16)")
    p.add_argument("--body-frequencies", type=int, default=None,
                   help="DCT frequencies the legs and trunk of text-only clips keep (text-only "
                        "row, --adherence; default: the generator's, 8; the arms keep "
                        "--frequencies)")
    return p


def main(argv=None):
    """Command-line entry point: prints the table; returns the rows. A missing checkpoint or a
    bad value raises (``python -m`` / ``physlab evaluate motion`` print it as one line, exit 2)."""
    args = _parser().parse_args(argv)
    if args.num_threads < 1:
        raise ValueError(f"--num-threads must be >= 1, got {args.num_threads}")
    import torch

    torch.set_num_threads(args.num_threads)
    if args.blending:
        rows = evaluate_blending(
            windows=args.windows, transition=args.transition, seed=args.seed,
            data_root=args.data_root, evaluator=None if args.no_evaluator else args.evaluator,
            generator=None if args.control is None else _load(args.control, "--control",
                                                                need_control=False),
            progress=not args.no_progress)
        table = format_blending_table(rows, args.transition)
        print(table)
        if args.out is not None:
            atomic_write_text(Path(args.out) / "blending.md", table + "\n")
        return rows
    if args.control is None:
        raise ValueError("--control is required (a control checkpoint, e.g. "
                         "data/motion/sketch2anim_control.pt) unless --blending is given")
    if args.take and args.no_3d:
        raise ValueError("--take chooses the 3D table's windows; drop --no-3d")
    if args.pose_detail and args.no_3d:
        raise ValueError("--pose-detail splits the 3D table's pose error; drop --no-3d")
    if args.condition_scale != 1.0 and args.no_3d:
        raise ValueError("--condition-scale applies to the 3D table's controlled rows; drop "
                         "--no-3d")
    takes = tuple(args.take or TEST_TAKES)
    rows = {} if args.no_3d else evaluate(args.control, single_controlnet=args.single_controlnet,
                    double_controlnet=args.double_controlnet,
                    windows=args.windows, steps=args.steps, guidance=args.guidance,
                    control_guidance=args.control_guidance,
                    condition_scale=args.condition_scale,
                    seed=args.seed, out=args.out, progress=not args.no_progress,
                    data_root=args.data_root,
                    body_constraints=not args.no_body_constraints,
                    foot_lock=not args.no_foot_lock, frequencies=args.frequencies,
                    body_frequencies=args.body_frequencies,
                    guidance_variants=args.guidance_variants, pose_detail=args.pose_detail,
                    takes=takes, text_model=not args.no_text_model,
                    evaluator=None if args.no_evaluator else args.evaluator)
    if args.detail is not None:
        print(format_detail(detail_kept(args.control, content=args.detail,
                                        statistic=args.detail_statistic,
                                        windows=args.detail_windows,
                                        progress=not args.no_progress,
                                        data_root=args.data_root)))
        print()
    adherence = None
    if args.adherence:
        adherence = text_adherence(args.control, seeds=args.adherence_seeds,
                                   steps=args.steps, guidance=args.guidance,
                                   progress=not args.no_progress,
                                   data_root=args.data_root, frequencies=args.frequencies,
                                   body_frequencies=args.body_frequencies,
                                   text_model=not args.no_text_model)
    if rows:
        print(format_table(rows, takes))
        if args.pose_detail:
            print()
            print(format_pose_breakdown(rows))
    if args.sketch:
        evaluator = None if args.no_evaluator else args.evaluator
        protocols = SKETCH_PROTOCOLS if args.protocol == "both" else (args.protocol,)
        for protocol in protocols:
            print()
            print(format_sketch_table(evaluate_sketch(
                args.control, windows=args.windows, steps=args.steps, seed=args.seed,
                noise=args.sketch_noise, progress=not args.no_progress,
                data_root=args.data_root, out=args.out, protocol=protocol,
                lifter=args.lifter, direct_2d=args.direct_2d, retrieval=args.retrieval,
                evaluator=evaluator, guidance_only=args.guidance_only,
                guidance_variants=args.guidance_variants),
                args.sketch_noise, protocol))
            if args.ablation:
                pairs = [a.split("=", 1) for a in args.ablation]
                bad = [a for a, p in zip(args.ablation, pairs) if len(p) != 2]
                if bad:
                    raise ValueError(f"--ablation needs NAME=PATH, got {bad[0]!r}")
                print()
                print(format_sketch_table(evaluate_alignment_ablation(
                    dict(pairs), windows=args.windows, steps=args.steps, seed=args.seed,
                    noise=args.sketch_noise, progress=not args.no_progress,
                    data_root=args.data_root, protocol=protocol, evaluator=evaluator,
                    out=args.out), args.sketch_noise, protocol))
    if adherence is not None:
        print()
        print(format_adherence(adherence))
    if args.out is not None and rows:
        print(f"wrote {args.out / 'table.md'} and {args.out / 'rows.json'}")
        if adherence is not None:
            atomic_write_text(args.out / "adherence.md", format_adherence(adherence) + "\n")
            atomic_write_text(args.out / "adherence.json", json.dumps(adherence, indent=1))
            print(f"wrote {args.out / 'adherence.md'} and {args.out / 'adherence.json'}")
    return rows


if __name__ == "__main__":
    from physlab._cli import guard

    sys.exit(guard("python -m physlab.motion.evaluate", main))
