"""The storyboard camera of Sketch2Anim (supp. B): an orthographic view ``P(x, v)`` of the
22-joint skeleton, and the augmentations that make projected mocap look like a user's sketch.

**Convention.** World coordinates are metres, y up; a canonical clip starts at the origin
facing ``+z`` (:func:`~physlab.motion.features.canonicalize`), so its left hand is at
``+x``. A :class:`Camera` with every angle 0 looks at the character from the front, along
``−z``. Its Euler angles (degrees) are

* ``yaw`` — the camera orbits the vertical axis; positive moves it towards the character's
  *right* side (``yaw = 90``: the character walks to the right of the picture);
* ``pitch`` — the camera rises and looks down; positive = from above (a storyboard's
  3/4 view: pitch 15–30°, yaw ±45°);
* ``roll`` — the picture turns counter-clockwise about the view axis.

The rotation from world to camera axes is ``R = R_z(roll) R_x(pitch) R_y(yaw)`` (intrinsic
Z-X-Y, :func:`~physlab.motion.skeleton.euler_to_matrix`), and the projection keeps the first
two camera axes, scaled: ``P(x) = s · (R x)[:2]``.

**Normalised image coordinates** ``(u, v)``: ``u`` to the right, ``v`` *up*, one unit = one
metre at ``scale = 1``, origin where the world origin projects. A sketch drawn in pixels
(``x`` right, ``y`` *down*, as images are) converts with :func:`to_pixels` /
:func:`from_pixels` given the pixel position of the origin and the pixels per unit; the
camera's ``scale`` then stands for how big the character was drawn.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dataset import TRAJECTORY_JOINT_NAMES
from .skeleton import JOINT_NAMES, PARENTS, euler_to_matrix, topological_order

__all__ = ["Camera", "to_pixels", "from_pixels", "random_camera", "perturb_proportions",
           "perturb_joints", "sketch_kwargs", "BODY_PARTS", "PITCH_RANGE", "YAW_RANGE", "SCALE_RANGE",
           "PROPORTION_RANGE", "JOINT_NOISE"]

#: Sketch2Anim supp. B, camera view augmentation: pitch and yaw ranges (degrees), scale range;
#: roll stays 0.
PITCH_RANGE, YAW_RANGE, SCALE_RANGE = (0.0, 30.0), (-45.0, 45.0), (0.8, 1.2)
#: Body proportion perturbation: factor range of a body part's bones.
PROPORTION_RANGE = (0.6, 1.6)
#: Random joint perturbation: standard deviation of the Gaussian noise, normalised units.
JOINT_NOISE = 0.02
#: The bones (named by their child joint) of each body part whose proportions a sketch may
#: get wrong: both legs (thigh, shin, foot), the spine with neck and head, both arms (upper
#: arm, forearm).
BODY_PARTS = {
    "leg": (4, 5, 7, 8, 10, 11),
    "spine": (3, 6, 9, 12, 15),
    "arm": (18, 19, 20, 21),
}


def _angle(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value):
        raise ValueError(f"Camera {name} must be a finite number of degrees, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Camera:
    """Orthographic storyboard camera (module docstring for the axes).

    Parameters
    ----------
    scale : float > 0, normalised image units per metre.
    pitch, yaw, roll : float, degrees.
    """
    scale: float = 1.0
    pitch: float = 0.0
    yaw: float = 0.0
    roll: float = 0.0

    def __post_init__(self):
        for name in ("pitch", "yaw", "roll"):
            object.__setattr__(self, name, _angle(getattr(self, name), name))
        s = _angle(self.scale, "scale")
        if not s > 0:
            raise ValueError(f"Camera scale must be > 0 (image units per metre), got {s!r}")
        object.__setattr__(self, "scale", s)

    @property
    def rotation(self):
        """``(3, 3)`` world-to-camera rotation ``R_z(roll) R_x(pitch) R_y(yaw)``; its rows are
        the picture's right and up axes and the direction towards the camera."""
        return euler_to_matrix([self.roll, self.pitch, self.yaw], "ZXY")

    @property
    def projection_matrix(self):
        """``(2, 3)`` matrix ``s · R[:2]`` of :meth:`project`: normalised image coordinates of
        a world point ``x`` are ``projection_matrix @ x``."""
        return self.scale * self.rotation[:2]

    @property
    def view_direction(self):
        """``(3,)`` unit vector the camera looks along (world coordinates)."""
        return -self.rotation[2]

    def project(self, joints):
        """``P(x, v)``: ``(..., 3)`` world points (m) → ``(..., 2)`` normalised image
        coordinates ``s · (R x)[:2]`` (``u`` right, ``v`` up)."""
        x = np.asarray(joints, dtype=float)
        if x.ndim < 1 or x.shape[-1] != 3:
            raise ValueError(f"joints must have shape (..., 3) in metres (e.g. (T, 22, 3)), got "
                             f"{x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError("joints contain NaN or inf")
        return x @ self.projection_matrix.T

    def to_dict(self):
        """JSON-ready ``{"scale", "pitch", "yaw", "roll"}``."""
        return {"scale": self.scale, "pitch": self.pitch, "yaw": self.yaw, "roll": self.roll}

    @classmethod
    def from_dict(cls, d):
        """Inverse of :meth:`to_dict`; unknown keys are an error naming them."""
        if not isinstance(d, dict):
            raise TypeError(f"a camera must be a dict with keys scale, pitch, yaw, roll; got "
                            f"{type(d).__name__}")
        unknown = sorted(set(d) - {"scale", "pitch", "yaw", "roll"})
        if unknown:
            raise ValueError(f"unknown camera keys {unknown}; use scale, pitch, yaw, roll")
        return cls(**d)


def _pixel_args(origin, pixels_per_unit):
    o = np.asarray(origin, dtype=float)
    if o.shape != (2,) or not np.all(np.isfinite(o)):
        raise ValueError(f"origin must be the (x, y) pixel where the world origin projects, got "
                         f"{origin!r}")
    k = float(pixels_per_unit)
    if not np.isfinite(k) or k <= 0:
        raise ValueError(f"pixels_per_unit must be > 0, got {pixels_per_unit!r}")
    return o, k


def to_pixels(uv, origin, pixels_per_unit):
    """Normalised image coordinates ``(..., 2)`` (v up) → pixels ``(..., 2)`` (x right,
    y down): ``x = o_x + k u``, ``y = o_y − k v``."""
    o, k = _pixel_args(origin, pixels_per_unit)
    uv = np.asarray(uv, dtype=float)
    if uv.ndim < 1 or uv.shape[-1] != 2:
        raise ValueError(f"uv must have shape (..., 2), got {uv.shape}")
    return np.stack([o[0] + k * uv[..., 0], o[1] - k * uv[..., 1]], axis=-1)


def from_pixels(xy, origin, pixels_per_unit):
    """Inverse of :func:`to_pixels`: pixels (y down) → normalised coordinates (v up)."""
    o, k = _pixel_args(origin, pixels_per_unit)
    xy = np.asarray(xy, dtype=float)
    if xy.ndim < 1 or xy.shape[-1] != 2:
        raise ValueError(f"xy must have shape (..., 2) pixels, got {xy.shape}")
    return np.stack([(xy[..., 0] - o[0]) / k, (o[1] - xy[..., 1]) / k], axis=-1)


def _rng(rng):
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def _range(r, name):
    lo, hi = (float(v) for v in r)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"{name} must be a (low, high) pair of finite numbers with low <= "
                         f"high, got {r!r}")
    return lo, hi


def random_camera(rng=None, pitch=PITCH_RANGE, yaw=YAW_RANGE, scale=SCALE_RANGE, roll=0.0):
    """A camera drawn uniformly from Sketch2Anim's view augmentation (supp. B): pitch in
    [0°, 30°], yaw in [−45°, 45°], scale in [0.8, 1.2], roll 0 (each range can be changed)."""
    g = _rng(rng)
    (p0, p1), (y0, y1), (s0, s1) = (_range(pitch, "pitch"), _range(yaw, "yaw"),
                                    _range(scale, "scale"))
    return Camera(scale=g.uniform(s0, s1), pitch=g.uniform(p0, p1), yaw=g.uniform(y0, y1),
                  roll=_angle(roll, "roll"))


def perturb_proportions(points, rng=None, factor=PROPORTION_RANGE, parts=tuple(BODY_PARTS)):
    """Body proportion perturbation (supp. B): each body part of :data:`BODY_PARTS` in
    ``parts`` gets one factor drawn uniformly from ``factor``, its bones (2D or 3D vectors from
    parent to child) are scaled by it and everything below them moves along; the pelvis stays.

    Parameters
    ----------
    points : (..., 22, d) float array, joints (a projected keypose: d = 2).
    rng : seed or numpy Generator. factor : (low, high) range, or a float for a fixed factor.
    parts : names from :data:`BODY_PARTS`.

    Returns
    -------
    (array of the input's shape, dict part -> factor used).
    """
    x = np.asarray(points, dtype=float)
    if x.ndim < 2 or x.shape[-2] != len(JOINT_NAMES):
        raise ValueError(f"points must have shape (..., {len(JOINT_NAMES)}, d), got {x.shape}")
    unknown = [p for p in parts if p not in BODY_PARTS]
    if unknown:
        raise ValueError(f"unknown body parts {unknown}; choose from {sorted(BODY_PARTS)}")
    g = _rng(rng)
    if isinstance(factor, (int, float, np.integer, np.floating)):
        lo = hi = float(factor)
        if not lo > 0:
            raise ValueError(f"factor must be > 0, got {factor!r}")
    else:
        lo, hi = _range(factor, "factor")
        if not lo > 0:
            raise ValueError(f"factor must be a range of positive numbers, got {factor!r}")
    scale = np.ones(len(JOINT_NAMES))
    used = {}
    for part in parts:
        used[part] = float(g.uniform(lo, hi))
        scale[list(BODY_PARTS[part])] = used[part]
    out = np.empty_like(x)
    out[..., 0, :] = x[..., 0, :]
    for j in topological_order(PARENTS):
        p = PARENTS[j]
        if p >= 0:
            out[..., j, :] = out[..., p, :] + scale[j] * (x[..., j, :] - x[..., p, :])
    return out, used


def perturb_joints(points, rng=None, sigma=JOINT_NOISE):
    """Random joint perturbation (supp. B): Gaussian noise of standard deviation ``sigma``
    (normalised units) added to every coordinate."""
    x = np.asarray(points, dtype=float)
    if not (np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be a finite number >= 0, got {sigma!r}")
    return x + _rng(rng).normal(0.0, float(sigma), x.shape)


def sketch_kwargs(condition, camera, rng=None, noise=0.0, proportions=None):
    """A 3D condition (:class:`~physlab.motion.dataset.Condition`) as it would be drawn in
    ``camera``'s view: the ``keypose_2d`` / ``trajectories_2d`` / ``camera`` / ``keypose_at``
    keywords of :func:`physlab.motion.generate`, the points projected by :meth:`Camera.project`.

    Parameters
    ----------
    condition : a Condition (``keypose`` (22, 3), ``key_frame``, ``trajectory`` (N, 6, 3),
        ``mask`` (N, 6)).
    camera : :class:`Camera`.
    rng : seed or Generator for the augmentations.
    noise : float >= 0, :func:`perturb_joints` sigma on every drawn point (supp. B: 0.02).
    proportions : None or a factor range for :func:`perturb_proportions` of the keypose
        (supp. B: :data:`PROPORTION_RANGE`).
    """
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be a physlab.motion.camera.Camera, got {camera!r}")
    g = _rng(rng)
    key = camera.project(condition.keypose)                                # (22, 2)
    if proportions is not None:
        key, _ = perturb_proportions(key, g, factor=proportions)
    trajs = {name: camera.project(condition.trajectory[condition.mask[:, c], c])
             for c, name in enumerate(TRAJECTORY_JOINT_NAMES) if condition.mask[:, c].any()}
    if noise:
        key = perturb_joints(key, g, noise)
        trajs = {k: perturb_joints(v, g, noise) for k, v in trajs.items()}
    return {"keypose_2d": key, "trajectories_2d": trajs, "camera": camera,
            "keypose_at": "first" if condition.key_frame == 0 else "last"}
