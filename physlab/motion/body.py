"""Body constraints of a generated clip: rigid bones and feet on the ground.

A diffusion model that denoises joint positions (either feature representation of
:mod:`~physlab.motion.features`) predicts every joint independently, so nothing forces a
bone to keep its length from frame to frame or a foot to stay above the floor; an inference
guidance that pulls a few joints onto their targets makes it worse (it drags one joint, not
the body). :func:`rigid_bones` projects a clip onto a skeleton with constant bone lengths
(keeping every bone's direction), :func:`ground_feet` lifts frames whose feet sink into
the floor and :func:`lock_feet` removes foot skating: a foot that is low and slow is in
contact, so it stays where it landed while the leg follows by two-bone inverse kinematics
(the classic foot-skate cleanup of Kovar, Schreiner & Gleicher 2002, here without
re-timing). :func:`constrain_body` does all three; :class:`~physlab.motion.sampling.Generator`
applies it to every clip unless told not to.

Shapes: joints ``(T, 22, 3)`` (or ``(B, T, 22, 3)``) in metres, y up, floor at ``y = 0``,
joint order and tree of :mod:`~physlab.motion.skeleton`.
"""
from __future__ import annotations

import numpy as np

from .skeleton import FOOT_JOINTS, PARENTS, bone_lengths, topological_order

__all__ = ["clip_bone_lengths", "rigid_bones", "ground_feet", "foot_contacts", "two_bone_ik",
           "lock_feet", "constrain_body", "FLOOR_TOLERANCE", "CONTACT_HEIGHT", "CONTACT_SPEED",
           "LEG_CHAINS", "LOCK_KEEP"]

#: A foot this far below the floor (m) counts as sinking in :func:`ground_feet`'s checks.
FLOOR_TOLERANCE = 0.02
#: :func:`foot_contacts`: a toe below this height (m) ...
CONTACT_HEIGHT = 0.05
#: ... moving horizontally slower than this (m/s, averaged over the two adjacent frame
#: steps) is in contact. Real Bandai-Namco walks plant the toe at 0.0–0.3 m/s and lift it
#: at 1–4 m/s; a generated foot that slides while planted moves at 0.5–2 m/s.
CONTACT_SPEED = 2.0
#: :func:`lock_feet` keeps this fraction of a planted foot's slide. Measured on the 64
#: held-out windows of ``python -m physlab.motion.evaluate`` (foot skating / AUJ of text
#: only, networks only, guided; real clips 0.153 / 0.26): no lock 0.44 / 0.34, 0.37 / 0.53,
#: 0.35 / 0.42; keep 0.3 at 1.5 m/s 0.29 / 0.18, 0.27 / 0.21, 0.23 / 0.18;
#: keep 0 (a hard lock) at 2 m/s 0.21 / 1.01, 0.22 / 0.41, 0.18 / 0.48; keep 0.15 at 2 m/s
#: 0.21 / 0.72, 0.23 / 0.27, 0.18 / 0.31; keep 0 at 2.5 m/s and 7 cm 0.12 / 1.75, 0.20 /
#: 0.83, 0.15 / 1.15. A harder lock trades sliding for jerk where the foot is stopped.
LOCK_KEEP = 0.15
#: Largest rate (m/frame) at which :func:`lock_feet`'s offset may change outside a contact run,
#: on top of the toe's own motion. Two contact runs a frame apart (a low shuffling foot, just
#: under :data:`CONTACT_SPEED`) otherwise leave the foot one frame to cover what both locks
#: held back: a guided slow walk jumped 0.22 m (6x its median step) where a stroke ended.
FADE_STEP = 0.05
#: (hip, knee, ankle, toe) joint indices of the left and right leg.
LEG_CHAINS = ((1, 4, 7, 10), (2, 5, 8, 11))


def _check(joints, name="joints"):
    x = np.asarray(joints, dtype=float)
    if x.ndim not in (3, 4) or x.shape[-2:] != (len(PARENTS), 3) or x.shape[-3] < 1:
        raise ValueError(f"{name} must have shape (T, {len(PARENTS)}, 3) or (B, T, "
                         f"{len(PARENTS)}, 3) in metres, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains NaN or inf")
    return x


def clip_bone_lengths(joints):
    """Per-bone length of a clip, the median over its frames: ``(22,)`` (``(B, 22)`` for a
    batch; entry 0, the pelvis, is 0). The median ignores the few frames a guidance or a
    bad denoising step stretched."""
    x = _check(joints)
    d = bone_lengths(x.reshape(-1, len(PARENTS), 3)).reshape(x.shape[:-2] + (-1,))  # (..., T, 21)
    out = np.zeros(x.shape[:-3] + (len(PARENTS),))
    out[..., 1:] = np.median(d, axis=-2)
    return out


def rigid_bones(joints, lengths=None):
    """Project a clip onto constant bone lengths, keeping the pelvis and every bone's
    direction: walking the tree from the pelvis, ``x'_j = x'_p + L_j (x_j − x_p)/|x_j − x_p|``.

    Parameters
    ----------
    joints : (T, 22, 3) or (B, T, 22, 3) float array (m).
    lengths : None (each clip's :func:`clip_bone_lengths`) or a (22,) / (B, 22) array of
        bone lengths (m; entry 0 unused), e.g. those of a keypose the user drew.

    Returns
    -------
    Array of the input's shape: every bone's length is ``lengths[j]`` in every frame. A
    bone of zero length in a frame keeps its direction from the skeleton's median pose.
    """
    x = _check(joints)
    L = clip_bone_lengths(x) if lengths is None else np.asarray(lengths, dtype=float)
    if L.shape != x.shape[:-3] + (len(PARENTS),) or not np.all(np.isfinite(L)) or np.any(L < 0):
        raise ValueError(f"lengths must be None or finite non-negative bone lengths of shape "
                         f"{x.shape[:-3] + (len(PARENTS),)}, got {np.shape(lengths)}")
    out = np.empty_like(x)
    out[..., 0, :] = x[..., 0, :]
    for j in topological_order(PARENTS):
        p = PARENTS[j]
        if p < 0:
            continue
        d = x[..., j, :] - x[..., p, :]                                      # (..., T, 3)
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        fallback = np.median(d, axis=-2, keepdims=True)                      # (..., 1, 3)
        d = np.where(n > 1e-9, d, fallback)
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        out[..., j, :] = out[..., p, :] + L[..., j, None, None] * d / np.maximum(n, 1e-12)
    return out


def ground_feet(joints, floor=0.0, feet=FOOT_JOINTS):
    """Lift every frame whose lowest foot joint is below ``floor`` by that much (the whole
    body, so bones stay rigid); other frames are unchanged.

    Parameters
    ----------
    joints : (T, 22, 3) or (B, T, 22, 3) float array (m).
    floor : float, floor height (m).
    feet : joint indices that may not go below the floor (default ankles and toes).

    Returns
    -------
    Array of the input's shape.
    """
    x = _check(joints)
    low = x[..., list(feet), 1].min(axis=-1)                                 # (..., T)
    lift = np.maximum(float(floor) - low, 0.0)
    out = x.copy()
    out[..., 1] += lift[..., None]
    return out


def _runs(mask):
    """(start, stop) of every run of True in a 1-D bool array (stop exclusive)."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(np.int8)))
    return list(zip(d[0::2], d[1::2]))


def foot_contacts(joints, fps=20.0, height=CONTACT_HEIGHT, speed=CONTACT_SPEED, min_frames=2,
                  floor=0.0):
    """Frames in which each toe touches the ground: ``y_t − floor < height`` and the
    horizontal speed ``½(|x_{t+1} − x_t| + |x_t − x_{t−1}|)_xz · fps < speed`` (one-sided at
    the ends); runs shorter than ``min_frames`` are dropped.

    Parameters
    ----------
    joints : (T, 22, 3) float array (m), T >= 2.
    fps : float > 0. height, speed : thresholds (m, m/s). min_frames : int >= 1.

    Returns
    -------
    (T, 2) bool array, columns left and right toe (:data:`LEG_CHAINS`).
    """
    x = _check(joints)
    if x.ndim != 3 or len(x) < 2:
        raise ValueError(f"joints must be one clip of shape (T >= 2, 22, 3), got {x.shape}")
    if not fps > 0 or not height > 0 or not speed > 0 or int(min_frames) < 1:
        raise ValueError(f"fps, height and speed must be > 0 and min_frames >= 1, got fps="
                         f"{fps}, height={height}, speed={speed}, min_frames={min_frames}")
    toes = x[:, [c[3] for c in LEG_CHAINS]]                                  # (T, 2, 3)
    step = np.linalg.norm(np.diff(toes[..., [0, 2]], axis=0), axis=-1) * fps  # (T-1, 2)
    v = np.empty((len(x), 2))
    v[0], v[-1] = step[0], step[-1]
    v[1:-1] = 0.5 * (step[1:] + step[:-1])
    c = (toes[..., 1] - floor < height) & (v < speed)
    for k in range(2):
        for a, b in _runs(c[:, k]):
            if b - a < int(min_frames):
                c[a:b, k] = False
    return c


def two_bone_ik(root, mid, end, l1, l2):
    """Place the middle joint of a two-bone chain so that it reaches ``end``.

    ``root`` stays; the end goes to ``end`` if ``l2 − l1 < |end − root| < l1 + l2``, else as
    near as the chain reaches along the same direction; the middle joint bends in the plane
    of the current ``mid`` (law of cosines: ``cos α = (l1² + d² − l2²) / (2 l1 d)`` at the
    root). Bone lengths ``l1`` (root–mid) and ``l2`` (mid–end) hold exactly.

    Parameters
    ----------
    root, mid, end : (..., 3) arrays (the current root and middle joint, the end's target).
    l1, l2 : (...) or scalar bone lengths > 0.

    Returns
    -------
    (mid', end') : (..., 3) arrays.
    """
    root, mid, end = (np.asarray(a, dtype=float) for a in (root, mid, end))
    l1, l2 = np.asarray(l1, dtype=float)[..., None], np.asarray(l2, dtype=float)[..., None]
    d = end - root
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    u = d / np.maximum(dist, 1e-12)
    dist = np.clip(dist, np.abs(l1 - l2) + 1e-6, l1 + l2 - 1e-6)
    end = root + u * dist
    pole = mid - root
    pole = pole - np.sum(pole * u, axis=-1, keepdims=True) * u               # ⟂ to the chain
    pn = np.linalg.norm(pole, axis=-1, keepdims=True)
    pole = np.where(pn > 1e-9, pole / np.maximum(pn, 1e-12), _any_perpendicular(u))
    cos_a = np.clip((l1 ** 2 + dist ** 2 - l2 ** 2) / (2 * l1 * dist), -1.0, 1.0)
    return root + l1 * (cos_a * u + np.sqrt(1 - cos_a ** 2) * pole), end


def _any_perpendicular(u):
    a = np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    p = np.cross(u, a)
    return p / np.maximum(np.linalg.norm(p, axis=-1, keepdims=True), 1e-12)


def lock_feet(joints, contacts=None, pinned=None, blend=3, keep=LOCK_KEEP, fps=20.0):
    """Foot-skate cleanup: in every contact run a toe keeps only the fraction ``keep`` of
    its horizontal slide (``q_t = q_a + keep (p_t − p_a)``, centred so that the run's mean
    offset is zero; ``keep = 0`` holds it at the median of its positions; the height is
    kept), the foot moves with it rigidly and the knee follows by :func:`two_bone_ik` from
    the unmoved hip, so every bone keeps its length. Over ``blend`` frames before and after a
    run the offset fades out linearly, so the foot eases into and out of its lock; between
    runs close together it ramps straight from one to the next, at most :data:`FADE_STEP`
    per frame (longer ramps take frames from the runs' ends).

    Parameters
    ----------
    joints : (T, 22, 3) float array (m), one clip with rigid bones (:func:`rigid_bones`).
    contacts : None (:func:`foot_contacts` of the clip) or a (T, 2) bool array.
    pinned : None or a (T, 2) bool array of frames whose toe must not move (e.g. frames where
        the guidance put that foot on its trajectory condition, or the keypose frame): they
        are never locked, and the offset ramps in linearly from them (at most
        :data:`FADE_STEP` per frame, over at least ``blend + 1`` frames), so no jump is added
        next to a condition.
    blend : int >= 0, fade length in frames.
    keep : float in [0, 1], the fraction of a contact's slide that is kept (0 = a hard lock,
        1 = unchanged).
    fps : float, passed to :func:`foot_contacts`.

    Returns
    -------
    (T, 22, 3) array. Where a hip is too far from its locked toe for the leg to reach, the
    foot gets as near as the straight leg allows.
    """
    x = _check(joints)
    if x.ndim != 3:
        raise ValueError(f"joints must be one clip of shape (T, 22, 3), got {x.shape}")
    T = len(x)
    c = foot_contacts(x, fps=fps) if contacts is None else np.asarray(contacts, dtype=bool)
    pin = np.zeros((T, 2), dtype=bool) if pinned is None else np.asarray(pinned, dtype=bool)
    for name, a in (("contacts", c), ("pinned", pin)):
        if a.shape != (T, 2):
            raise ValueError(f"{name} must be a ({T}, 2) bool array (left, right toe per "
                             f"frame), got shape {a.shape}")
    if int(blend) < 0:
        raise ValueError(f"blend must be an integer >= 0 frames, got {blend!r}")
    if not 0 <= keep <= 1:
        raise ValueError(f"keep must be in [0, 1] (the fraction of a contact's slide kept), "
                         f"got {keep!r}")
    blend = int(blend)
    out = x.copy()
    for k, (hip, knee, ankle, toe) in enumerate(LEG_CHAINS):
        runs = _runs(c[:, k] & ~pin[:, k])
        if not runs:
            continue
        target = np.zeros((T, 3))
        anchored = np.zeros(T, dtype=bool)
        for a, b in runs:
            p = x[a:b, toe][:, [0, 2]]                                     # (n, 2) xz
            if keep == 0:
                q = np.median(p, axis=0)[None]
            else:                      # the slide scaled by `keep`, centred on the original
                q = p[:1] + keep * (p - p[:1])
                q = q - (q - p).mean(axis=0)
            target[a:b, [0, 2]] = q - p
            anchored[a:b] = True
        delta = _fade(target, anchored, runs, blend, pin[:, k])
        moved = np.flatnonzero(np.any(delta != 0.0, axis=1))
        if not len(moved):
            continue
        l1 = np.linalg.norm(x[moved, knee] - x[moved, hip], axis=-1)
        l2 = np.linalg.norm(x[moved, ankle] - x[moved, knee], axis=-1)
        new_knee, new_ankle = two_bone_ik(x[moved, hip], x[moved, knee],
                                          x[moved, ankle] + delta[moved], l1, l2)
        out[moved, knee] = new_knee
        out[moved, toe] = new_ankle + (x[moved, toe] - x[moved, ankle])
        out[moved, ankle] = new_ankle
    return out


def _fade(target, anchored, runs, blend, pinned):
    """The lock offsets of :func:`lock_feet`: ``target`` at the ``anchored`` (contact) frames,
    zero at the ``pinned`` frames and ``blend + 1`` frames away from every run, linear in
    between — so two runs close together are joined by a straight ramp instead of a jump.
    Where a ramp would move the toe more than :data:`FADE_STEP` per frame, the runs give up
    their end frames to it until it does not (a foot that shuffles between two plants is not
    held through both; a lock next to a trajectory condition starts later)."""
    T = len(target)
    anchored = anchored.copy()
    near = np.zeros(T + 2 * (blend + 1), dtype=bool)                  # frames -(blend+1)..
    for a, b in runs:
        near[a + 1:b + 2 * blend + 1] = True          # frames a - blend .. b - 1 + blend
    zero_t = np.flatnonzero(~near) - (blend + 1)                       # zero-offset anchors
    pin_t = np.flatnonzero(pinned)
    zero_t = np.union1d(zero_t, pin_t)
    if len(pin_t):                     # ramp in over at least blend + 1 frames from a pin
        dist = np.abs(np.arange(T)[:, None] - pin_t[None]).min(axis=1)
        anchored &= dist > blend
    ts = np.arange(T)
    while True:
        run_t = np.flatnonzero(anchored)
        t_all = np.concatenate([run_t, zero_t])
        order = np.argsort(t_all, kind="stable")
        t_all = t_all[order]
        v_all = np.concatenate([target[run_t], np.zeros((len(zero_t), 3))])[order]
        delta = np.stack([np.interp(ts, t_all, v_all[:, d]) for d in range(3)], axis=1)
        rate = np.linalg.norm(np.diff(delta, axis=0), axis=1)                # (T-1,)
        ramp = ~(anchored[:-1] & anchored[1:])                   # steps outside the runs
        bad = np.flatnonzero((rate > FADE_STEP + 1e-12) & ramp)
        if not len(bad):
            return delta
        for s in bad:                  # free the run frames at the ends of a too-steep ramp
            i = np.searchsorted(t_all, s, side="right")          # t_all[i-1] <= s < t_all[i]
            for j in (i - 1, i):
                if 0 <= j < len(t_all) and 0 <= t_all[j] < T and anchored[t_all[j]]:
                    anchored[t_all[j]] = False


def constrain_body(joints, lengths=None, floor=0.0, lock=True, pinned=None):
    """The body constraints of a generated clip (Sketch2Anim's guidance is said to keep a
    plausible body; here it is enforced): :func:`rigid_bones`, then, with ``lock``,
    :func:`lock_feet` (``pinned`` as there; single clips only), then :func:`ground_feet`."""
    x = rigid_bones(joints, lengths)
    if lock:
        if x.ndim == 4:
            x = np.stack([lock_feet(xi, pinned=pinned) for xi in x])
        else:
            x = lock_feet(x, pinned=pinned)
    return ground_feet(x, floor=floor)
