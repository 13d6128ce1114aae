"""max_penetration (deepest vertex of one body inside another, px) and measured_stable_dt."""
import warnings

import numpy as np
import pytest

from physlab import physanimator as pa
from physlab.mesh import grid_mesh


def _two_squares(overlap):
    """Two 10x10 px squares side by side, the right one shifted ``overlap`` px into the left."""
    m = grid_mesh(4, 4, 10.0, 10.0)
    a = pa.Body(m, offset=(0.0, 0.0))
    b = pa.Body(m, offset=(10.0 - overlap, 0.0))
    scene = pa.Scene([a, b], collisions=False)
    x = [np.stack([bd.X_canvas] * 3) for bd in scene.bodies]          # 3 identical frames
    return pa.Animation(np.arange(3) / 24, x, scene, 1e-3, 24.0), scene


@pytest.mark.parametrize("overlap", [1.0, 2.5, 4.0])
def test_depth_of_overlapping_squares_is_the_overlap(overlap):
    anim, _ = _two_squares(overlap)
    d = pa.max_penetration(anim)
    assert d.shape == (3,)
    np.testing.assert_allclose(d, overlap, atol=1e-9)   # the deepest vertex: an edge column


def test_apart_or_touching_is_zero_and_a_wrong_scene_is_named():
    anim, _ = _two_squares(-3.0)                         # 3 px apart
    assert np.all(pa.max_penetration(anim) == 0.0)
    single = pa.Scene([anim.scene.bodies[0]])
    with pytest.raises(ValueError, match="the animation has 2 bodies, the scene 1"):
        pa.max_penetration(anim, single)


def test_the_cfl_estimate_is_conservative_and_the_measured_limit_is_real():
    from physlab.demos.physanimator import ball_push_scene

    scene = ball_push_scene(E=1e5, size=80)
    dt, est = pa.measured_stable_dt(scene, duration=0.3)
    assert 1.0 <= dt / est < 64
    with warnings.catch_warnings():                     # "dt above the estimate": known
        warnings.simplefilter("ignore")
        pa.simulate(scene, 0.3, dt=dt, progress=False)  # stable at the measured limit
        with pytest.raises(pa.UnstableTimeStep):
            pa.simulate(scene, 0.3, dt=1.2 * dt, progress=False)
