"""The camera of the 3-D motion views: named view directions and a frame-the-scene placement.

:data:`CAMERAS` maps a view name to the direction from the focal point to the camera (the
character faces +z, its left is +x, y up); :func:`_camera_position` turns a name, a (3,)
direction or an explicit ``(position, focal_point, view_up)`` into a PyVista camera position
that frames given points in a perspective frustum; :func:`_view_direction` gives the unit
direction (the matplotlib view uses it for elevation and azimuth). Pure numpy.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CAMERAS"]

#: Named views: direction from the focal point to the camera (the character faces +z, its
#: left is +x). "side" looks at its right side, so forward (+z) points right on screen.
CAMERAS = {
    "front": (0.0, 0.15, 1.0),
    "side": (-1.0, 0.15, 0.0),
    "iso": (-1.0, 0.55, 1.25),
    "top": (0.0, 1.0, 1e-3),
}

_VIEW_ANGLE = 30.0             # degrees, VTK's default vertical field of view


def _view_direction(camera):
    if isinstance(camera, str):
        if camera not in CAMERAS:
            raise ValueError(f"camera must be one of {', '.join(CAMERAS)}, a view direction "
                             f"(3,) or (position, focal_point, view_up), got {camera!r}")
        v = np.array(CAMERAS[camera], float)
    else:
        v = np.asarray(camera, dtype=float)
        if v.shape != (3,) or not np.linalg.norm(v) > 0:
            raise ValueError(f"camera must be a name, a non-zero view direction (3,) or "
                             f"(position, focal_point, view_up), got {camera!r}")
    return v / np.linalg.norm(v)


def _camera_position(camera, points, size, pad=0.0, view_angle=_VIEW_ANGLE, margin=1.06):
    """(position, focal_point, view_up) framing ``points`` (n, 3) from direction ``camera``.

    The focal point centres the points on screen (in the camera's right / up axes) and the
    distance is the smallest at which every point, grown by ``pad`` metres, lies inside the
    perspective frustum (vertical angle ``view_angle``, aspect ``width / height``):
    ``dist >= (|p·right| + pad) / tan(fov_h / 2) + p·dir`` and likewise with ``up``."""
    if not isinstance(camera, str) and np.shape(camera) == (3, 3):
        pos, foc, up = (tuple(map(float, v)) for v in np.asarray(camera, float))
        return [pos, foc, up]
    d = _view_direction(camera)
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    up0 = np.array([0, 0, -1.0]) if abs(d[1]) > 0.999 else np.array([0, 1.0, 0])
    right = np.cross(up0, d)
    right /= np.linalg.norm(right)
    up = np.cross(d, right)
    f = (p.min(0) + p.max(0)) / 2
    u, v = (p - f) @ right, (p - f) @ up
    f = f + right * (u.min() + u.max()) / 2 + up * (v.min() + v.max()) / 2
    q = p - f
    tv = np.tan(np.radians(view_angle) / 2)
    th = tv * size[0] / size[1]
    dist = max(np.max((np.abs(q @ right) + pad) / th + q @ d + pad),
               np.max((np.abs(q @ up) + pad) / tv + q @ d + pad))
    dist = margin * max(dist, 0.5)
    return [tuple(f + dist * d), tuple(f), tuple(up)]
