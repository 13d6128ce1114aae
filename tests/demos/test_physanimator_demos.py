"""physlab.demos.physanimator: the lesson pipeline (drawing → mesh → simulation → frames)."""
import warnings

import numpy as np
import pytest
from matplotlib.figure import Figure

from physlab import datasets
from physlab import physanimator as pa
from physlab.demos import physanimator as demo


@pytest.mark.parametrize("call", [
    lambda: demo.element_demo(stretch_y=-0.5),  # inverted triangles
    lambda: demo.flow_field_demo(direction_deg=30.0),
    lambda: demo.ball_push_demo(E=1e5, duration=0.3),
    lambda: demo.stroke_demo(duration=0.3),
    lambda: demo.flag_demo(duration=0.3),
])
def test_callbacks_return_drawable_figures(call, tmp_path):
    fig = call()
    assert isinstance(fig, Figure)
    fig.savefig(tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 5_000


def test_ball_push_demo_reports_unstable_step():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fig = demo.ball_push_demo(dt=0.02, duration=0.5)
    assert any("UnstableTimeStep" in t.get_text() for ax in fig.axes for t in ax.texts)


def test_youngs_modulus_sweep_is_monotone():
    _, strains = demo.youngs_modulus_sweep(Es=(5e4, 1e5, 2e5, 4e5), duration=0.8)
    assert all(a > b for a, b in zip(strains, strains[1:])), strains


def test_animate_renders_moving_frames_and_control_images():
    r = demo.animate(demo.tree_scene(), duration=0.5, fps=24)
    F, H, W, _ = r.frames.shape
    assert F == r.animation.n_frames == 13 and (H, W) == (512, 512)  # t = 0 and 12 frames
    assert r.controls.shape == (F, H, W)
    assert np.abs(r.frames[-1].astype(int) - r.frames[0]).mean() > 0.5  # the tree moved
    dark = r.controls < 128
    assert 0.005 < dark.mean() < 0.2  # line art: some lines, mostly white


@pytest.mark.parametrize("direction_deg", [0.0, 180.0, 90.0, -90.0])
def test_the_tree_stays_on_its_canvas_under_the_strongest_wind(direction_deg):
    """Lesson 05's slider goes up to s = 8e4; the crown must stay in the picture for 2 s."""
    from physlab import physanimator as pa

    scene = demo.tree_scene(strength=8e4, direction_deg=direction_deg)
    x = pa.simulate(scene, 2.0, progress=False).x[0]                      # (F, n, 2)
    W, H = scene.size
    assert x[..., 0].min() >= 0 and x[..., 0].max() <= W
    assert x[..., 1].min() >= 0 and x[..., 1].max() <= H


def test_animate_renders_a_selection_of_frames():
    r = demo.animate(demo.tree_scene(), duration=0.5, fps=24, control=False, frames=4)
    assert list(r.frame_index) == [0, 4, 8, 12] and len(r.frames) == 4
    with pytest.raises(ValueError, match=r"frames must be indices in 0\.\.12"):
        demo.animate(demo.tree_scene(), duration=0.5, fps=24, control=False, frames=[13])


@pytest.mark.parametrize("name", datasets.ANIMATED_DRAWINGS)
def test_pipeline_on_real_drawings(real_data, name):
    """Every AnimatedDrawings character: mask → Triangle mesh → wind + pinned feet → frames."""
    d = datasets.animated_drawing(name)
    H, W = d.image.shape[:2]
    body = demo.drawing_body(d, E=2e5, mask=d.notes["mask"])
    X = body.mesh.X
    assert body.mesh.min_angle() >= 19.9 and len(body.mesh.tris) > 50
    feet = X[X[:, 1] > np.quantile(X[:, 1], 0.97)]
    rigs = [pa.FixedRig(center=tuple(p), radius=0.03 * H) for p in feet[:3]]
    y = float(np.quantile(X[:, 1], 0.3))
    stroke = pa.EnergyStroke([[0.0, y], [float(W), y]], "wind", strength=5e4, range=0.25 * H,
                             speed=1.5 * W)
    scene = pa.Scene([body], strokes=[stroke], rigs=rigs, size=(W, H), damping=2.0)
    r = demo.animate(scene, duration=0.5, fps=12, control=False)
    assert np.all(np.isfinite(r.animation.x[0]))
    assert r.frames.shape == (r.animation.n_frames, H, W, 3)
    moved = np.abs(r.animation.x[0][-1] - r.animation.x[0][0]).max()
    assert moved > 1.0, f"{name}: the wind did not move the drawing ({moved:.2f} px)"
    # the first frame reproduces the drawing where its mask is (warp at rest = identity)
    m = d.notes["mask"] & (d.image[..., 3] > 250)
    err = np.abs(r.frames[0].astype(float) - d.image[..., :3])[m].mean()
    assert err < 12.0, f"{name}: rest frame differs from the drawing by {err:.1f} grey levels"
