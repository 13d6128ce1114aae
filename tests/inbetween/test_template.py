"""Template construction (Brodt & Bessmeltsev Sec. 4.2): mesh, handle vertices, texture."""
import numpy as np
import pytest
from _drawings import bar_drawing

from physlab.inbetween.skeleton import Skeleton
from physlab.inbetween.template import as_rgba_float, build_template


@pytest.fixture(scope="module")
def bar():
    return bar_drawing()


def test_mesh_covers_the_drawing_with_handles_as_vertices(bar):
    img, sk = bar
    tpl = build_template(img, sk)
    K = len(sk) + len(sk.bones)
    assert tpl.handle_tris.shape == (K,) and tpl.handle_bary.shape == (K, 3)
    assert np.all(tpl.handle_vertices >= 0)                     # all inside: inserted
    assert np.allclose(tpl.X[tpl.handle_vertices], sk.handles())
    assert np.allclose(tpl.handle_positions(tpl.X), sk.handles())
    assert np.allclose(tpl.handle_matrix() @ tpl.X, sk.handles())
    assert tpl.mesh.min_angle() >= 19.0                          # Triangle's q20
    # the (grown) mesh covers every drawn pixel, including the ink outline
    from physlab.mesh import point_in_mesh
    ys, xs = np.nonzero(img[..., 3] > 0)
    assert point_in_mesh(tpl.mesh, np.c_[xs, ys]).all()
    # identity deformation reproduces the drawing
    out = tpl.render(tpl.X)
    assert np.abs(out - as_rgba_float(img)).max() < 1e-5
    assert tpl.layers == ()


def test_handles_outside_the_mask_use_extrapolated_barycentrics(bar):
    img, sk = bar
    far = sk.with_xy(sk.xy + [[0, 0], [0, 0], [25, 0]])  # hand joint beyond the bar's end
    tpl = build_template(img, far)
    k = far.index("hand")
    assert tpl.handle_vertices[k] == -1
    assert np.allclose(tpl.handle_positions(tpl.X)[k], far.xy[k])
    # the constraint moves with the mesh: translate everything
    assert np.allclose(tpl.handle_positions(tpl.X + [3.0, 4.0])[k], far.xy[k] + [3, 4])


def test_coincident_joints_share_a_vertex(bar):
    img, sk = bar
    sk2 = Skeleton(("root", "hip", "elbow", "hand"), [-1, 0, 1, 2],
                   np.vstack([sk.xy[:1], sk.xy]))
    tpl = build_template(img, sk2)
    assert tpl.handle_vertices[0] == tpl.handle_vertices[1] >= 0


def test_bad_inputs(bar):
    img, sk = bar
    with pytest.raises(ValueError, match="outside the 240x120 image"):
        build_template(img, sk.with_xy(sk.xy + [0, 200]))
    with pytest.raises(ValueError, match="empty"):
        build_template(img, sk, mask=np.zeros(img.shape[:2], bool))
    with pytest.raises(ValueError, match="mask shape"):
        build_template(img, sk, mask=np.ones((10, 10), bool))
    with pytest.raises(TypeError, match="Skeleton"):
        build_template(img, sk.xy)
    with pytest.raises(ValueError, match="image"):
        build_template(img[..., 0:2], sk)
    with pytest.raises(ValueError, match="NaN"):
        build_template(np.full((50, 50, 3), np.nan), sk)
    blank = np.full((120, 240, 3), 255, np.uint8)
    with pytest.raises(ValueError, match="empty"):
        build_template(blank, sk)
