"""physlab.inbetween.skinning: bone transforms, BBW weights, LBS, ARAP, the bending limb."""
import numpy as np
import pytest

from physlab.fem import deformation_gradients, polar_rotation, rest_shape
from physlab.inbetween.skeleton import Skeleton
from physlab.inbetween.skinning import (
    arap_deform,
    bbw_weights,
    bending_limb_example,
    bone_transforms,
    flipped_triangles,
    lbs_deform,
    skeleton_deform,
    triangle_area_ratios,
)
from physlab.mesh import grid_mesh, triangle_areas, triangulate_polygon, vertex_indices


def rot(deg):
    t = np.radians(deg)
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def apply(A, P):
    """Affine (2, 3) ``A`` applied to points (m, 2)."""
    return P @ A[:, :2].T + A[:, 2]


@pytest.fixture(scope="module")
def limb():
    """The 120° bent arm, deformed by LBS and ARAP (≈ 180 vertices)."""
    return bending_limb_example(120.0)


@pytest.fixture(scope="module")
def strip():
    """A 24 × 4 grid strip with a 3-joint skeleton on its centre line (every centre-line
    vertex lies on a bone) and its weights."""
    m = grid_mesh(24, 4, 240.0, 40.0, origin=(10.0, 30.0))
    sk = Skeleton(("a", "b", "c"), np.array([-1, 0, 1]), [[20.0, 50.0], [130.0, 50.0],
                                                          [240.0, 50.0]])
    hv = vertex_indices(m, sk.handles())
    X, tris = np.array(m.X), np.array(m.tris)
    return X, tris, sk, hv, bbw_weights(X, tris, sk, hv)


def ad_skeleton():
    """AnimatedDrawings-like: root and hip coincide (zero-length bone), three limbs from the hip."""
    names = ("root", "hip", "torso", "left_leg", "right_leg")
    xy = [[100.0, 100.0], [100.0, 100.0], [100.0, 40.0], [70.0, 160.0], [130.0, 160.0]]
    return Skeleton(names, np.array([-1, 0, 1, 1, 1]), xy)


def ad_mesh(sk):
    poly = np.array([[60.0, 20.0], [140.0, 20.0], [150.0, 175.0], [50.0, 175.0]])
    m = triangulate_polygon(poly, max_area=60.0, min_angle=25.0, points=sk.handles())
    return np.array(m.X), np.array(m.tris), vertex_indices(m, sk.handles())


# ---------------------------------------------------------------------------------- transforms
def test_bone_transform_single_bone_analytic():
    rest = Skeleton(("p", "c"), np.array([-1, 0]), [[1.0, 2.0], [3.0, 2.0]])  # length 2, +x
    pose = rest.with_xy([[5.0, 5.0], [5.0, 8.0]])  # length 3, +y: turned 90°, stretched 1.5×
    A = bone_transforms(rest, pose)[0]
    assert np.allclose(A[:, :2], [[0.0, -1.0], [1.5, 0.0]])  # R(90°) diag(1.5, 1)
    assert np.allclose(apply(A, rest.xy), pose.xy)
    # perpendicular direction is rotated, not stretched
    assert np.allclose(A[:, :2] @ [0.0, 1.0], [-1.0, 0.0])
    R = bone_transforms(rest, pose, stretch=False)[0]
    assert np.allclose(R[:, :2], rot(90))
    assert np.allclose(apply(R, rest.xy[:1]), pose.xy[:1])


def test_bone_transforms_map_every_bone_and_are_rigid_for_rigid_poses():
    rng = np.random.default_rng(0)
    sk = Skeleton(("r", "a", "b", "c", "d"), np.array([-1, 0, 1, 1, 0]), rng.uniform(0, 100, (5, 2)))
    pose = sk.with_xy(rng.uniform(0, 100, (5, 2)))
    A = bone_transforms(sk, pose)
    for (p, c), Ab in zip(sk.bones, A):
        assert np.allclose(apply(Ab, sk.xy[[p, c]]), pose.xy[[p, c]])
    Q, t = rot(37), np.array([12.0, -5.0])
    A = bone_transforms(sk, sk.with_xy(sk.xy @ Q.T + t))
    assert np.allclose(A[:, :, :2], Q) and np.allclose(A[:, :, 2], t)
    # identity pose: identity transforms
    assert np.allclose(bone_transforms(sk, sk), np.eye(2, 3))


def test_bone_transforms_zero_length_bone_inherits():
    sk = ad_skeleton()
    pose = sk.with_xy(sk.xy @ rot(30).T + [7.0, 3.0])
    A = bone_transforms(sk, pose)
    # bone 0 = root→hip has zero length: no rotation of its own, root translation
    assert np.allclose(A[0, :, :2], np.eye(2))
    assert np.allclose(apply(A[0], sk.xy[:1]), pose.xy[:1])
    # a zero-length bone under a rotating parent takes the parent's linear part
    sk2 = Skeleton(("a", "b", "c"), np.array([-1, 0, 1]), [[0.0, 0.0], [10.0, 0.0], [10.0, 0.0]])
    p2 = sk2.with_xy([[0.0, 0.0], [0.0, 10.0], [0.0, 10.0]])
    A2 = bone_transforms(sk2, p2)
    assert np.allclose(A2[1], A2[0]) and np.all(np.isfinite(A2))


# ---------------------------------------------------------------------------------- weights
def test_bbw_weights_partition_of_unity_bounds_and_samples(strip):
    X, _, _, hv, W = strip
    assert W.shape == (len(X), 2)
    assert W.min() >= 0.0 and W.max() <= 1.0
    assert np.allclose(W.sum(1), 1.0, atol=1e-12)
    # every vertex on a bone interior belongs to that bone (igl.boundary_conditions samples)
    on_line = np.isclose(X[:, 1], 50.0)
    assert np.allclose(W[on_line & (X[:, 0] >= 20) & (X[:, 0] < 130), 0], 1.0)
    assert np.allclose(W[on_line & (X[:, 0] > 130) & (X[:, 0] <= 240), 1], 1.0)
    # the shared elbow joint is split evenly; the end joints are their bone's
    assert np.allclose(W[hv[:3]], [[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]])
    # smooth falloff across the elbow: the upper-arm weight decreases along the arm
    top = np.isclose(X[:, 1], 30.0)
    order = np.argsort(X[top, 0])
    assert np.all(np.diff(W[top, 0][order]) <= 1e-9)


def test_bbw_weights_mirror_symmetric_and_single_bone():
    m = grid_mesh(20, 4, 200.0, 40.0)
    X, tris = np.array(m.X), np.array(m.tris)
    sk = Skeleton(("a", "b", "c"), np.array([-1, 0, 1]), [[20.0, 20.0], [100.0, 20.0],
                                                          [180.0, 20.0]])
    W = bbw_weights(X, tris, sk, vertex_indices(m, sk.handles()))
    # the mesh's checkerboard diagonals are mirror-symmetric about x = 100
    mirror = vertex_indices(m, np.c_[200.0 - X[:, 0], X[:, 1]])
    assert np.allclose(W[:, 0], W[mirror, 1], atol=1e-6)
    one = Skeleton(("a", "b"), np.array([-1, 0]), [[40.0, 20.0], [160.0, 20.0]])
    W1 = bbw_weights(X, tris, one, vertex_indices(m, one.handles()))
    assert np.allclose(W1, 1.0)


def test_bbw_weights_zero_length_bone_and_reference(limb):
    sk = ad_skeleton()
    X, tris, hv = ad_mesh(sk)
    W = bbw_weights(X, tris, sk, hv)
    assert W.shape == (len(X), 4)
    assert np.all(W[:, 0] == 0.0)  # the zero-length root→hip bone
    assert np.allclose(W.sum(1), 1.0) and W.min() >= 0.0 and W.max() <= 1.0
    # root = hip vertex is shared by the three limbs
    assert np.allclose(W[hv[0], 1:], 1.0 / 3.0)
    # fixed reference: forearm weight at the middle of the arm's upper edge
    X, W = limb.X, limb.weights
    assert np.allclose(W[limb.handle_vertices], [[1, 0], [0.5, 0.5], [0, 1], [1, 0], [0, 1]])
    k = np.argmin(np.linalg.norm(X - [160.0, 96.0], axis=1))
    assert W[k, 1] == pytest.approx(0.5, abs=0.05)


def test_bbw_handle_vertices_minus_one_are_ignored(strip):
    X, tris, sk, hv, W = strip
    hv2 = hv.copy()
    hv2[[3, 4]] = -1  # midpoints: still sampled, they lie on the bones
    assert np.allclose(bbw_weights(X, tris, sk, hv2), W)


# ---------------------------------------------------------------------------------- LBS
def test_lbs_identity_pose_returns_rest_exactly(limb):
    A = bone_transforms(limb.skeleton_rest, limb.skeleton_rest)
    x = lbs_deform(limb.X, limb.weights, A)
    assert np.array_equal(x, limb.X)


def test_lbs_analytic_blend():
    X = np.array([[0.0, 0.0], [1.0, 0.0]])
    A = np.stack([np.eye(2, 3), np.c_[np.eye(2), [2.0, 4.0]]])
    W = np.array([[1.0, 0.0], [0.25, 0.75]])
    assert np.allclose(lbs_deform(X, W, A), [[0.0, 0.0], [2.5, 3.0]])


def test_rigid_skeleton_motion_gives_rigid_result(limb):
    Q, t = rot(-50), np.array([30.0, -12.0])
    rigid = limb.X @ Q.T + t
    pose = limb.skeleton_rest.with_xy(limb.skeleton_rest.xy @ Q.T + t)
    args = (limb.X, limb.tris, limb.skeleton_rest, pose, limb.handle_vertices)
    assert np.allclose(skeleton_deform(*args, "lbs", weights=limb.weights), rigid, atol=1e-9)
    assert np.allclose(skeleton_deform(*args, "arap"), rigid, atol=1e-9)
    # from the rest shape ARAP has to find the rotation itself
    x = arap_deform(limb.X, limb.tris, limb.handle_vertices, pose.handles(), max_iter=300)
    assert np.allclose(x, rigid, atol=1e-6)


# ---------------------------------------------------------------------------------- ARAP
def test_arap_handles_at_rest_return_rest(limb):
    X, hv = limb.X, limb.handle_vertices
    x = arap_deform(X, limb.tris, hv, X[hv], max_iter=5)
    assert np.allclose(x, X, atol=1e-10)


def test_arap_handles_land_exactly_on_targets(limb):
    x = limb.results["arap"]
    assert np.array_equal(x[limb.handle_vertices], limb.skeleton_pose.handles())
    rng = np.random.default_rng(1)
    hv = np.array([0, 5, 17, 40, -1])
    tg = limb.X[np.maximum(hv, 0)] + rng.normal(0, 3.0, (5, 2))
    x = arap_deform(limb.X, limb.tris, hv, tg, max_iter=3)
    assert np.array_equal(x[hv[:4]], tg[:4])


def arap_gradient(X, tris, x):
    """∇ of Σ_t A_t ‖F_t − R_t‖²_F (R_t the polar rotation), the ARAP energy of Eq. (ARAP)."""
    Dm_inv, area = rest_shape(X, tris)
    F = deformation_gradients(x, X, tris, Dm_inv)
    G = 2 * area[:, None, None] * (F - polar_rotation(F)) @ np.swapaxes(Dm_inv, 1, 2)
    g = np.zeros_like(x)
    np.add.at(g, tris[:, 1], G[:, :, 0])
    np.add.at(g, tris[:, 2], G[:, :, 1])
    np.add.at(g, tris[:, 0], -G[:, :, 0] - G[:, :, 1])
    return g


def test_arap_result_is_stationary_point_of_the_arap_energy():
    """Independent check that libigl's 2D ARAP minimises Eq. (ARAP): zero gradient at the
    free vertices once converged, none at the start."""
    ex = bending_limb_example(60.0, deform=False)
    hv, tg = ex.handle_vertices, ex.skeleton_pose.handles()
    x = arap_deform(ex.X, ex.tris, hv, tg, max_iter=400)
    free = np.setdiff1d(np.arange(len(ex.X)), hv)
    g_end = np.abs(arap_gradient(ex.X, ex.tris, x)[free]).max()
    x0 = ex.X.copy()
    x0[hv] = tg
    g_start = np.abs(arap_gradient(ex.X, ex.tris, x0)[free]).max()
    assert g_end < 1e-7 * g_start


# ---------------------------------------------------------------------------------- bending limb
def test_bending_limb_failure_modes(limb):
    """At a 120° elbow LBS collapses the joint; ARAP keeps the areas (and is a lot closer)."""
    X, tris, e = limb.X, limb.tris, limb.elbow_tris
    area0 = triangle_areas(X, tris[e]).sum()
    loss = {m: 1.0 - triangle_areas(x, tris[e]).sum() / area0 for m, x in limb.results.items()}
    crushed = {m: int(np.sum(limb.area_ratios(m) < 0.25)) for m in limb.results}
    assert loss["lbs"] > 0.25 and loss["arap"] < 0.1
    assert loss["lbs"] > 3 * loss["arap"]
    assert crushed["lbs"] >= 10 and crushed["lbs"] > 3 * crushed["arap"]
    assert len(flipped_triangles(X, limb.results["lbs"], tris)) >= 1
    # away from the elbow both are rigid: area ratios stay near 1
    far = np.setdiff1d(np.arange(len(tris)), e)
    for m in limb.results:
        assert np.allclose(limb.area_ratios(m)[far], 1.0, atol=0.35)
    # fixed reference numbers (Triangle's mesh is deterministic)
    assert loss["lbs"] == pytest.approx(0.316, abs=0.02)
    assert loss["arap"] == pytest.approx(0.064, abs=0.02)


def test_bending_limb_straight_is_rest():
    ex = bending_limb_example(0.0)
    for x in ex.results.values():
        assert np.allclose(x, ex.X, atol=1e-9)
        assert len(flipped_triangles(ex.X, x, ex.tris)) == 0


def test_flipped_triangles_and_area_ratios():
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    tris = np.array([[0, 1, 2], [1, 3, 2]])
    x = X.copy()
    x[3] = [0.2, 0.2]  # folds the second triangle over
    assert flipped_triangles(X, x, tris).tolist() == [1]
    x[3] = [0.5, 0.5]  # collapses it onto the diagonal
    assert flipped_triangles(X, x, tris).tolist() == [1]
    assert np.allclose(triangle_area_ratios(X, 2 * X, tris), 4.0)
    # either rest orientation
    assert flipped_triangles(X, X @ rot(90).T, tris[:, ::-1]).size == 0


# ---------------------------------------------------------------------------------- errors
def test_bad_inputs_raise(limb, strip):
    X, tris, hv = limb.X, limb.tris, limb.handle_vertices
    sk, W = limb.skeleton_rest, limb.weights
    A = bone_transforms(sk, limb.skeleton_pose)
    with pytest.raises(ValueError, match="different topology"):
        bone_transforms(sk, Skeleton(sk.names, np.array([-1, 0, 0]), sk.xy))
    with pytest.raises(ValueError, match="different joints"):
        skeleton_deform(X, tris, sk, ad_skeleton(), np.full(9, -1))
    with pytest.raises(ValueError, match=r"weights must have shape \(n, B\)"):
        lbs_deform(X, W[:, :1], A)
    with pytest.raises(ValueError, match="must sum to 1"):
        lbs_deform(X, 2 * W, A)
    with pytest.raises(ValueError, match=r"transforms must have shape \(B, 2, 3\)"):
        lbs_deform(X, W, A[:, :, :2])
    with pytest.raises(ValueError, match=r"X must have shape \(n, 2\)"):
        bbw_weights(np.c_[X, X[:, :1]], tris, sk, hv)
    with pytest.raises(ValueError, match=r"handle_vertices must have shape \(5,\)"):
        bbw_weights(X, tris, sk, hv[:4])
    with pytest.raises(ValueError, match=r"handle_vertices\[2\] = 999 is not a vertex"):
        bbw_weights(X, tris, sk, np.array([4, 5, 999, 7, 8]))
    with pytest.raises(ValueError, match="not a vertex"):
        arap_deform(X, tris, [0, len(X)], X[:2])
    with pytest.raises(ValueError, match=r"targets must have shape \(5, 2\)"):
        arap_deform(X, tris, hv, X[:4])
    with pytest.raises(ValueError, match="two different targets"):
        arap_deform(X, tris, [3, 3], [[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(ValueError, match="at least one handle"):
        arap_deform(X, tris, [-1], [[0.0, 0.0]])
    with pytest.raises(ValueError, match="x0 must have the shape"):
        arap_deform(X, tris, hv, X[hv], x0=X[:-1])
    with pytest.raises(ValueError, match="method must be"):
        skeleton_deform(X, tris, sk, sk, hv, method="dqs")
    with pytest.raises(ValueError, match="tris refer to vertices"):
        bbw_weights(X, tris + len(X), sk, hv)
    # a bone with no mesh vertex of its own
    Xs, ts, sks, hvs, _ = strip
    off = sks.with_xy(sks.xy + [3.0, 3.0])  # off the grid lines, no handle vertices
    with pytest.raises(ValueError, match="no mesh vertex of their own"):
        bbw_weights(Xs, ts, off, np.full(5, -1))
    # a mesh piece without any handle
    two = np.concatenate([Xs, Xs + [0.0, 200.0]])
    with pytest.raises(ValueError, match="connected piece"):
        bbw_weights(two, np.concatenate([ts, ts + len(Xs)]), sks, hvs)
    with pytest.raises(ValueError, match="no bone of positive length"):
        z = Skeleton(("a", "b"), np.array([-1, 0]), [[20.0, 50.0], [20.0, 50.0]])
        bbw_weights(Xs, ts, z, np.full(3, -1))

