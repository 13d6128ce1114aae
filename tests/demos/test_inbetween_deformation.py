"""physlab.demos.inbetween_deformation: lesson 06 callbacks (Brodt & Bessmeltsev 2024 Eq. 1)."""
import re

import numpy as np
import pytest
from matplotlib.figure import Figure

from physlab.demos import inbetween_deformation as demo


def _flipped_in_title(fig):
    """The flipped-triangle count the arm widget reports in its title."""
    m = re.search(r"flipped triangles (\d+)", fig.get_suptitle())
    assert m, f"no flipped count in the title {fig.get_suptitle()!r}"
    return int(m.group(1))


def _drawable(fig, tmp_path, n_axes):
    assert isinstance(fig, Figure)
    assert len(fig.axes) == n_axes, [a.get_title() for a in fig.axes]
    fig.savefig(tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 5_000


@pytest.fixture(scope="module")
def tpl():
    return demo.character_template(size=256)


# ---------------------------------------------------------------------------- widget callbacks
@pytest.mark.parametrize("shoulder, elbow, style", [
    (-60.0, -60.0, "flat"), (-150.0, 150.0, "shaded"), (60.0, -150.0, "sketchy")])
def test_arm_pose_demo_draws_two_panels_and_reports_no_flips(shoulder, elbow, style, tmp_path):
    fig = demo.arm_pose_demo(shoulder_deg=shoulder, elbow_deg=elbow, style=style)
    _drawable(fig, tmp_path, 3)  # drawing, density mesh, colour bar
    assert _flipped_in_title(fig) == 0
    err = float(re.search(r"max handle error ([\d.e+-]+) px", fig.get_suptitle()).group(1))
    assert err < 0.05


@pytest.mark.parametrize("method", list(demo.LIMB_METHODS))
def test_limb_demo_draws_each_method(method, tmp_path):
    fig = demo.limb_demo(angle_deg=120.0, method=method)
    _drawable(fig, tmp_path, 3)  # whole arm, elbow zoom, colour bar
    counts = dict(re.findall(r"(LBS|ARAP|Eq\. 1): (\d+)", fig.get_suptitle()))
    assert counts["Eq. 1"] == "0" and int(counts["LBS"]) > 0


@pytest.mark.parametrize("call, match", [
    (lambda: demo.arm_pose_demo(shoulder_deg=400.0), "shoulder_deg"),
    (lambda: demo.arm_pose_demo(elbow_deg=float("nan")), "elbow_deg"),
    (lambda: demo.arm_pose_demo(mu=0.0), "mu"),
    (lambda: demo.arm_pose_demo(style="oil paint"), "style"),
    (lambda: demo.limb_demo(method="skinning"), "method"),
    (lambda: demo.limb_demo(angle_deg=179.0), "angle_deg"),
    (lambda: demo.handle_matrix([0, -1, 3], 5), "handle_vertices"),
])
def test_bad_parameters_raise_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ---------------------------------------------------------------------------- static figures
def test_static_figures(tpl, tmp_path):
    _drawable(demo.template_figure(tpl), tmp_path, 3)
    _drawable(demo.density_figure(), tmp_path, 3)  # curves, level sets, colour bar
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    d = np.array([[0.0, 0.0], [-1.5, 0.5], [0.5, -1.5]])
    _drawable(demo.injective_step_figure(x, d), tmp_path, 2)


def test_solver_comparison_lbfgs_beats_gradient_methods(tpl, tmp_path):
    pose = demo.pose_arm(tpl.skeleton, -60.0, -60.0)
    fig, runs = demo.solver_comparison(tpl, pose, max_iter=400)
    _drawable(fig, tmp_path, 2)
    gd, sob, lbfgs = runs.values()
    assert lbfgs.converged and sob.converged and not gd.converged
    assert lbfgs.iterations < sob.iterations < gd.iterations == 400
    assert lbfgs.handle_error.max() < 1e-2


def test_limb_comparison_reproduces_the_ordering(tmp_path):
    fig, stats = demo.limb_comparison(angle_deg=120.0)
    _drawable(fig, tmp_path, 4)  # three deformers + colour bar
    loss = {m: s["area_loss"] for m, s in stats.items()}
    assert loss["lbs"] > loss["arap"] > loss["symmetric_dirichlet"]
    assert stats["lbs"]["flipped"] > 0 and stats["symmetric_dirichlet"]["flipped"] == 0
    assert stats["symmetric_dirichlet"]["min_ratio"] > 0


# ---------------------------------------------------------------------------- helpers
def test_handle_matrix_selects_vertices():
    x = np.arange(12.0).reshape(6, 2)
    B = demo.handle_matrix(np.array([4, 0, 2]), 6)
    np.testing.assert_array_equal(B @ x, x[[4, 0, 2]])


def test_densities_are_four_at_rest_and_under_rotation(tpl):
    np.testing.assert_allclose(demo.triangle_densities(tpl, tpl.X), 4.0)
    c, s = np.cos(0.7), np.sin(0.7)
    x = tpl.X @ np.array([[c, -s], [s, c]]).T + 3.0
    np.testing.assert_allclose(demo.triangle_densities(tpl, x), 4.0)


@pytest.mark.parametrize("angle", [30.0, 90.0, 170.0])
def test_limb_symmetric_dirichlet_reaches_the_handles_without_folds(angle):
    from physlab.inbetween.skinning import bending_limb_example, flipped_triangles

    ex = bending_limb_example(angle, deform=False)
    x = demo.limb_symmetric_dirichlet(ex)
    np.testing.assert_allclose(x[ex.handle_vertices], ex.skeleton_pose.handles(), atol=1e-3)
    assert len(flipped_triangles(ex.X, x, ex.tris)) == 0


def test_deform_pose_reports_rigid_pose_exactly(tpl):
    x, info = demo.deform_pose(tpl, demo.pose_arm(tpl.skeleton, 0.0, 0.0))
    np.testing.assert_allclose(x, tpl.X, atol=1e-9)
    assert info["flipped"] == 0 and np.isclose(info["energy_d"], 4.0)
