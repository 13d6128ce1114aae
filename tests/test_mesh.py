"""physlab.mesh: TriMesh, builders, masks → polygons → Triangle meshes, point location."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage as ndi

from physlab import datasets, mesh
from physlab.mesh import TriMesh

MIN_ANGLE_TOL = 19.9  # Triangle's q20 bound, measured on the output


def disk_mask(h=120, w=140, cx=70.0, cy=60.0, r=40.0):
    yy, xx = np.mgrid[0:h, 0:w]
    return (xx - cx) ** 2 + (yy - cy) ** 2 <= r**2


def boundary_shoelace(m):
    """Σ over boundary edges of cross(X_i, X_j) / 2: equals the mesh area iff the boundary is
    closed and runs the positive way round (Green's theorem)."""
    e = m.boundary_edges()
    a, b = m.X[e[:, 0]], m.X[e[:, 1]]
    return 0.5 * np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])


def point_segment_distance(p, A, B):
    """(m,) distance of points p (m, 2) to the nearest of the segments A[i] -> B[i]."""
    e = B - A  # (k, 2)
    w = p[:, None, :] - A[None]  # (m, k, 2)
    t = np.clip(np.einsum("mkd,kd->mk", w, e) / np.einsum("kd,kd->k", e, e), 0, 1)
    return np.linalg.norm(w - t[..., None] * e[None], axis=-1).min(axis=1)


# ---------------------------------------------------------------------------------- TriMesh
def test_triangle_areas_analytic_and_orientation():
    X = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 3.0]])
    np.testing.assert_allclose(mesh.triangle_areas(X, [[0, 1, 2], [0, 2, 1]]), [3.0, -3.0])
    np.testing.assert_allclose(mesh.triangle_angles(X, [[0, 1, 2]]).sum(), 180.0)
    np.testing.assert_allclose(mesh.triangle_angles(X, [[0, 1, 2]])[0, 0], 90.0)
    m = TriMesh(X, [[0, 2, 1]])
    assert not m.is_positively_oriented and m.oriented().is_positively_oriented
    assert m.oriented().areas[0] == pytest.approx(3.0)


def test_trimesh_validation_messages():
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [2.0, 0.0]])
    with pytest.raises(ValueError, match=r"triangle 1 .*\[0, 1, 3\]"):
        TriMesh(X, [[0, 1, 2], [0, 1, 3]])  # collinear: zero area
    with pytest.raises(ValueError, match="shape"):
        TriMesh(X[:, :1], [[0, 1, 2]])
    with pytest.raises(ValueError, match="finite"):
        TriMesh(np.where(X == 1.0, np.nan, X), [[0, 1, 2]])
    with pytest.raises(ValueError, match="does not exist"):
        TriMesh(X, [[0, 1, 7]])
    with pytest.raises(ValueError, match="at least one"):
        TriMesh(X, np.zeros((0, 3), int))
    m = TriMesh(X, [[0, 1, 2]])
    assert m.X.dtype == np.float64 and m.tris.dtype == np.int64
    with pytest.raises(ValueError):
        m.X[0, 0] = 5.0  # read-only: the mesh is immutable


def test_tiny_but_valid_triangle_is_accepted_at_any_scale():
    X = 1e-6 * np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert TriMesh(X, [[0, 1, 2]]).areas[0] == pytest.approx(5e-13)


# ---------------------------------------------------------------------------------- builders
def test_grid_mesh_analytic():
    m = mesh.grid_mesh(3, 2, 6.0, 4.0, origin=(1.0, -2.0))
    assert (m.n, m.n_tris) == (12, 12)
    assert m.areas.sum() == pytest.approx(24.0) and np.all(m.areas > 0)
    np.testing.assert_allclose(m.areas, 2.0)  # 2 x 2 cells
    assert len(m.boundary_edges()) == 2 * (3 + 2) and len(m.boundary_vertices()) == 2 * (3 + 2)
    assert len(m.edges()) == 3 * 3 + 2 * 4 + 3 * 2  # horizontal + vertical + diagonals
    assert m.min_angle() == pytest.approx(45.0)
    np.testing.assert_allclose(m.X.min(0), [1.0, -2.0])
    np.testing.assert_allclose(m.X.max(0), [7.0, 2.0])
    # reference: the first cell (vertices 0, 1, 4, 5) is split along 0-5, its neighbour along 2-5
    np.testing.assert_array_equal(m.tris[:4], [[0, 1, 5], [0, 5, 4], [1, 2, 5], [2, 6, 5]])
    assert boundary_shoelace(m) == pytest.approx(24.0)


def test_grid_diagonals_alternate():
    m = mesh.grid_mesh(4, 4, 4.0, 4.0)
    e = m.X[m.edges()]
    d = e[:, 1] - e[:, 0]
    diag = d[np.all(np.abs(d) > 0.5, axis=1)]
    slope = np.sign(diag[:, 0] * diag[:, 1])
    assert np.sum(slope > 0) == np.sum(slope < 0) == 8


@pytest.mark.parametrize("r", [1.0, 37.5])
def test_disk_mesh_area_and_quality(r):
    m = mesh.disk_mesh((10.0, -5.0), r)
    n = 48
    exact = 0.5 * n * r**2 * np.sin(2 * np.pi / n)  # reference: inscribed 48-gon
    assert m.area == pytest.approx(exact, rel=1e-12)
    assert m.area == pytest.approx(np.pi * r**2, rel=0.02)
    assert m.is_positively_oriented and m.min_angle() >= MIN_ANGLE_TOL
    assert 100 <= m.n_tris <= 600  # default max_area: a few hundred triangles at any scale
    assert boundary_shoelace(m) == pytest.approx(m.area)


def test_default_max_area_is_scale_invariant():
    counts = [mesh.disk_mesh((0, 0), r).n_tris for r in (0.01, 1.0, 300.0)]
    assert max(counts) - min(counts) <= 0.05 * max(counts)


def l_shape():
    return np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)


@pytest.mark.parametrize("reverse", [False, True])
def test_polygon_mesh_l_shape(reverse):
    P = l_shape()[::-1] if reverse else l_shape()
    m = mesh.polygon_mesh(P, max_area=0.02)
    assert m.area == pytest.approx(3.0, rel=1e-12)
    assert m.is_positively_oriented and m.min_angle() >= MIN_ANGLE_TOL
    assert np.abs(m.areas).max() <= 0.02 * (1 + 1e-9)
    np.testing.assert_allclose(m.X[:6], P)  # outline vertices come first, in order
    assert boundary_shoelace(m) == pytest.approx(3.0)


def test_triangulate_with_hole_and_points():
    outer = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], dtype=float)
    hole = np.array([[4, 4], [6, 4], [6, 6], [4, 6]], dtype=float)
    pts = np.array([[2.0, 2.0], [8.0, 7.5]])
    m = mesh.triangulate_polygon(outer, max_area=2.0, holes=[hole], points=pts)
    assert m.area == pytest.approx(100.0 - 4.0)
    np.testing.assert_allclose(m.X[8:10], pts)  # outline, hole, then points
    assert m.is_positively_oriented and m.min_angle() >= MIN_ANGLE_TOL
    tri, _ = mesh.locate_points(m, [[5.0, 5.0], [2.0, 2.0]])
    assert tri[0] == -1 and tri[1] >= 0
    assert boundary_shoelace(m) == pytest.approx(96.0)  # hole boundary runs the other way
    with pytest.raises(ValueError, match=r"points\[0\]"):
        mesh.triangulate_polygon(outer, points=[[5.0, 5.0]], holes=[hole])
    with pytest.raises(ValueError, match="min_angle"):
        mesh.triangulate_polygon(outer, min_angle=40)
    with pytest.raises(ValueError, match="zero area"):
        mesh.triangulate_polygon([[0, 0], [1, 1], [2, 2]])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(5, 40), scale=st.sampled_from([0.01, 1.0, 500.0]))
def test_random_star_polygons_mesh_exactly_with_quality(seed, n, scale):
    rng = np.random.default_rng(seed)
    th = np.sort(2 * np.pi * (np.arange(n) + rng.uniform(-0.3, 0.3, n)) / n)
    r = scale * rng.uniform(0.3, 1.0, n)
    P = np.stack([r * np.cos(th), r * np.sin(th)], axis=1)
    P = mesh.chamfer_corners(mesh.remove_sharp_corners(P, 20.0), 60.0)
    m = mesh.polygon_mesh(P)
    assert m.area == pytest.approx(mesh.polygon_area(P), rel=1e-9)  # the outline is kept exactly
    assert m.is_positively_oriented and m.min_angle() >= MIN_ANGLE_TOL
    assert boundary_shoelace(m) == pytest.approx(m.area, rel=1e-9)
    assert len(m.edges()) == m.n + m.n_tris - 1  # Euler: V - E + F = 1 for a disk
    c = m.X[m.tris].mean(1)  # centroids are found in their own triangle
    tri, bary = mesh.locate_points(m, c)
    np.testing.assert_array_equal(tri, np.arange(m.n_tris))
    np.testing.assert_allclose(bary, 1 / 3, atol=1e-9)


def test_strip_mesh_sizes():
    for n in (2_000, 20_000, 200_000):
        m = mesh.strip_mesh(n)
        assert abs(m.n_tris - n) <= 0.02 * n
        ext = np.ptp(m.X, axis=0)
        assert ext[0] / ext[1] == pytest.approx(10.0, rel=0.1)
        assert m.area == pytest.approx(m.n_tris / 2)  # unit cells, 2 triangles each


# ---------------------------------------------------------------------------------- masks
def test_mask_from_array_formats():
    m = disk_mask()
    for a in (m, m.astype(np.uint8) * 255, m.astype(np.uint8), m.astype(float),
              np.repeat((m * 255).astype(np.uint8)[..., None], 3, axis=2)):
        np.testing.assert_array_equal(mesh.mask_from_array(a), m)
    with pytest.raises(ValueError, match="foreground_mask"):
        mesh.mask_from_array(np.random.default_rng(0).integers(0, 255, (5, 5, 3)))


def test_foreground_mask_ink_outline_alpha_and_blank():
    from skimage.draw import circle_perimeter_aa

    img = np.full((120, 140, 3), 235, np.uint8)  # light paper
    rr, cc, val = circle_perimeter_aa(60, 70, 40)
    for k in range(-1, 2):  # a 3-px dark pen circle
        rr, cc, val = circle_perimeter_aa(60, 70, 40 + k)
        img[rr, cc] = np.minimum(img[rr, cc], (235 * (1 - val))[:, None].astype(np.uint8) + 20)
    iou = lambda a, b: (a & b).sum() / (a | b).sum()
    fm0 = mesh.foreground_mask(img, dilate_radius=0)  # Otsu, closing, hole filling
    assert iou(fm0, disk_mask(r=41.5)) > 0.97  # the pen's outer edge is at r = 41.5
    fm = mesh.foreground_mask(img)  # default: + 2 px dilation around the ink
    assert iou(fm, disk_mask(r=43.5)) > 0.97
    rgba = np.zeros((120, 140, 4), np.uint8)
    rgba[..., 3] = 255 * disk_mask()
    np.testing.assert_array_equal(mesh.foreground_mask(rgba), disk_mask())  # alpha is exact
    assert not mesh.foreground_mask(np.full((50, 50, 3), 200, np.uint8)).any()
    with pytest.raises(ValueError, match="mask_from_array"):
        mesh.foreground_mask(disk_mask())


def two_blobs():
    m = disk_mask(h=100, w=200, cx=50, cy=50, r=30) | disk_mask(h=100, w=200, cx=150, cy=50, r=20)
    m[2:4, 2:4] = True  # a speck below min_area
    return m


def test_two_blobs_give_two_meshes_largest_first():
    m = two_blobs()
    comps = mesh.mask_components(m)
    sizes = [c.sum() for c in comps]
    assert len(comps) == 2 and sizes == sorted(sizes, reverse=True)
    rgba = np.zeros(m.shape + (4,), np.uint8)
    rgba[m] = (200, 50, 50, 255)
    meshes = mesh.meshes_from_image(rgba)
    assert len(meshes) == 2
    # Douglas-Peucker chords cut up to epsilon px off convex outlines: ~7% of a 20-px disk
    np.testing.assert_allclose([me.area for me in meshes], [c.sum() for c in comps], rtol=0.08)
    fine = mesh.meshes_from_image(rgba, epsilon=0.5)
    np.testing.assert_allclose([me.area for me in fine], [c.sum() for c in comps], rtol=0.02)
    assert meshes[0].X[:, 0].max() < 100 < meshes[1].X[:, 0].min()  # x is the column: not flipped
    assert all(me.is_positively_oriented and me.min_angle() >= MIN_ANGLE_TOL for me in meshes)


def test_small_bodies_get_pixel_sized_triangles():
    m = np.zeros((40, 40), bool)
    m[10:22, 5:15] = True  # 120 px
    me = mesh.mesh_from_mask(m)
    assert me.n_tris <= 30 and np.abs(me.areas).max() <= mesh.MIN_PIXEL_AREA
    # Douglas-Peucker (epsilon 2 px) keeps 4 of the cut corners: 109.5 px² of 120 (reference)
    assert me.area == pytest.approx(109.5)
    assert mesh.mesh_from_mask(m, epsilon=0.25).area == pytest.approx(119.5)  # corners cut: 4 x 1/8


def test_boundary_polygon_of_disk():
    m = disk_mask()
    eps = 2.0
    P = mesh.boundary_polygon(m, epsilon=eps)
    assert mesh.polygon_area(P) > 0 and not np.allclose(P[0], P[-1]) and mesh.polygon_is_simple(P)
    assert mesh.polygon_area(P) == pytest.approx(m.sum(), rel=0.02)
    assert mesh.polygon_area(P) == pytest.approx(np.pi * 40**2, rel=0.02)
    assert len(P) < 60  # simplified (the raw contour has ~230 points)
    # every boundary pixel centre lies within epsilon + 1 px of the polygon
    edge = m & ~ndi.binary_erosion(m)
    iy, ix = np.nonzero(edge)
    d = point_segment_distance(np.stack([ix, iy], 1).astype(float), P, np.roll(P, -1, axis=0))
    assert d.max() <= eps + 1
    # x = column, y = row (y down): the disk spans x in 30..110, y in 20..100
    np.testing.assert_allclose(P.min(0), [29.5, 19.5], atol=0.6)
    np.testing.assert_allclose(P.max(0), [110.5, 100.5], atol=0.6)


def interior_angles(P):
    """(k,) interior angles (degrees) of a positively oriented polygon."""
    e1, e2 = P - np.roll(P, 1, 0), np.roll(P, -1, 0) - P
    turn = np.arctan2(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0], np.einsum("kd,kd->k", e1, e2))
    return 180.0 - np.degrees(turn)


def test_sharp_spike_is_cut_so_quality_holds():
    yy, xx = np.mgrid[0:120, 0:140]
    spike = (xx >= 105) & (xx <= 138) & (np.abs(yy - 60) <= (138 - xx) * 0.08)  # ~9° wedge
    m = disk_mask() | spike
    raw = mesh.boundary_polygon(m)
    assert interior_angles(raw).min() < 20.0  # Douglas-Peucker keeps a needle tip
    P = mesh.boundary_polygon(m, min_corner_angle=20.0)
    assert interior_angles(P).min() >= 20.0 and mesh.polygon_is_simple(P)
    P = mesh.boundary_polygon(m, min_corner_angle=20.0, chamfer_angle=60.0)
    assert interior_angles(P).min() >= 60.0 and mesh.polygon_is_simple(P)
    me = mesh.mesh_from_mask(m)
    assert me.min_angle() >= MIN_ANGLE_TOL and me.is_positively_oriented
    assert me.area == pytest.approx(m.sum(), rel=0.05)


def test_remove_sharp_corners_analytic():
    spike = np.array([[0, 0], [4, 0], [4, 1], [20, 1.5], [4, 2], [4, 3], [0, 3]], dtype=float)
    P = mesh.remove_sharp_corners(spike, 20.0)
    assert len(P) == 6 and not np.any(np.all(P == [20, 1.5], axis=1))
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    np.testing.assert_array_equal(mesh.remove_sharp_corners(square, 20.0), square)


@pytest.mark.parametrize("theta", [21.0, 25.0, 45.0])
def test_chamfer_restores_triangles_angle_bound_near_small_input_angles(theta):
    t = np.radians(theta)
    wedge = np.array([[0.0, 0.0], [20.0, 0.0], [20 * np.cos(t), 20 * np.sin(t)]])
    P = mesh.chamfer_corners(wedge, 60.0)
    assert len(P) == 4  # only the apex is below 60° (the base corners are 90° - theta/2)
    assert interior_angles(P).min() >= 60.0
    # analytic: the apex loses delta² sin(theta) / 2 with delta = 0.3 * 20 px
    lost = mesh.polygon_area(wedge) - mesh.polygon_area(P)
    assert lost == pytest.approx(0.5 * 6.0**2 * np.sin(t), rel=1e-9)
    assert mesh.polygon_mesh(P, max_area=1.0).min_angle() >= MIN_ANGLE_TOL


def test_mesh_from_mask_with_joint_points():
    m = disk_mask()
    joints = np.array([[70.0, 60.0], [80.0, 50.0], [70.0, 60.0]])  # root == hip, as in AD
    me = mesh.mesh_from_mask(m, points=joints)
    k = len(mesh.boundary_polygon(m, min_corner_angle=20.0, chamfer_angle=mesh.CHAMFER_ANGLE))
    np.testing.assert_allclose(me.X[k:k + 2], joints[:2])  # duplicates merged, order kept
    np.testing.assert_array_equal(mesh.vertex_indices(me, joints), [k, k + 1, k])
    assert mesh.vertex_indices(me, [[70.5, 60.0]])[0] == -1
    assert me.min_angle() >= MIN_ANGLE_TOL


# ---------------------------------------------------------------------------------- holes
def boundary_loop_count(m):
    """Number of closed boundary loops of a mesh (connected components of its boundary edges)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = m.boundary_edges()
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(m.n, m.n))
    n, labels = connected_components(g, directed=False)
    return len(np.unique(labels[np.unique(e)]))


def ring_mask(r_in=20.0, r_out=40.0, size=120):
    d = np.hypot(*(np.mgrid[:size, :size] - (size - 1) / 2))
    return (d <= r_out) & (d >= r_in)


def akimbo_character(size=256):
    """The procedural character with both hands on the hips (RGBA uint8): two enclosed gaps."""
    from physlab.inbetween import character_skeleton, pose_character, render_character

    sk = pose_character(character_skeleton(size), left_upper_arm=-10, left_forearm=110,
                        right_upper_arm=10, right_forearm=-110)
    return render_character(sk, "flat", size, seed=0)


def test_fill_small_holes_analytic():
    m = np.ones((30, 40), bool)
    m[5:8, 5:8] = False  # 9-px speckle
    m[5:11, 20:26] = False  # 36-px gap
    m[0:3, 35:40] = False  # a notch open to the border: no hole
    m[20, 20] = m[21, 21] = False  # two pixels touching at a corner: one 2-px hole
    m[20, 30:35] = m[21:25, 34] = False  # an L of 9 px, open nowhere
    holes = ~m
    holes[0:3, 35:40] = False
    filled = mesh.fill_small_holes(m)  # MIN_HOLE_AREA = 16 px
    np.testing.assert_array_equal(filled, m | (holes & ~(np.arange(40) >= 20)[None]
                                                 | holes & (np.arange(30) >= 20)[:, None]))
    assert filled[5:8, 5:8].all() and not filled[5:11, 20:26].any()
    assert not filled[0:3, 35:40].any()
    np.testing.assert_array_equal(mesh.fill_small_holes(m, 0), m)
    np.testing.assert_array_equal(mesh.fill_small_holes(m, 36), filled)  # 36 px: kept
    np.testing.assert_array_equal(mesh.fill_small_holes(m, 37), m | holes)
    np.testing.assert_array_equal(mesh.fill_small_holes(m, np.inf), m | holes)
    for bad in (-1, float("nan"), "big"):
        with pytest.raises(ValueError, match="min_hole_area must be"):
            mesh.fill_small_holes(m, bad)


def test_loops_are_disjoint_analytic():
    square = lambda c, h: np.array([[c - h, c - h], [c + h, c - h], [c + h, c + h], [c - h, c + h]])
    assert mesh.loops_are_disjoint([square(0, 2), square(0, 1)[::-1]])  # nested: fine
    assert not mesh.loops_are_disjoint([square(0, 2), square(1.5, 1)])  # crossing
    assert not mesh.loops_are_disjoint([square(0, 2), square(1, 1)])  # touching along an edge
    bowtie = np.array([[0.0, 0], [1, 1], [1, 0], [0, 1]])
    assert not mesh.loops_are_disjoint([bowtie]) and not mesh.polygon_is_simple(bowtie)


def test_ring_mask_gives_a_mesh_with_a_hole():
    m = ring_mask()
    outer, holes = mesh.boundary_loops(m)
    assert mesh.polygon_area(outer) > 0 and len(holes) == 1 and mesh.polygon_area(holes[0]) < 0
    assert mesh.loops_are_disjoint([outer] + holes)
    me = mesh.mesh_from_mask(m)
    assert boundary_loop_count(me) == 2
    assert me.area == pytest.approx(m.sum(), rel=0.03)  # 3760 px of the 20..40 ring
    assert me.area == pytest.approx(np.pi * (40**2 - 20**2), rel=0.03)
    # Green's theorem holds with the hole: it runs the other way round (interior on the left)
    assert boundary_shoelace(me) == pytest.approx(me.area)
    assert not mesh.point_in_mesh(me, [[59.5, 59.5], [59.5, 45.0]]).any()  # the hole is empty
    assert me.is_positively_oriented and me.min_angle() >= MIN_ANGLE_TOL
    assert me.area == pytest.approx(3801.0, abs=1.0)  # reference (ε = 2 px chords)
    # the explicit way to mesh over holes; a smaller hole than min_hole_area is filled too
    for full in (mesh.mesh_from_mask(m, min_hole_area=np.inf),
                 mesh.mesh_from_mask(m, min_hole_area=ring_mask(0, 20).sum() + 1)):
        assert boundary_loop_count(full) == 1
        assert full.area == pytest.approx(ring_mask(0, 40).sum(), rel=0.03)
    with pytest.raises(ValueError, match="outside the region to mesh"):
        mesh.mesh_from_mask(m, points=[[59.5, 59.5]])  # a joint in the hole


def test_thin_ring_walls_mesh_without_crossing_loops():
    m = ring_mask(12.0, 14.5, size=40)  # a 2.5-px wall: Douglas-Peucker chords would cross
    me = mesh.mesh_from_mask(m)
    assert boundary_loop_count(me) == 2
    assert me.area == pytest.approx(m.sum(), rel=0.1)
    assert boundary_shoelace(me) == pytest.approx(me.area)


def test_arm_on_the_hip_leaves_a_hole():
    img = akimbo_character()
    fm = mesh.foreground_mask(img)  # alpha path: the gaps are transparent
    gaps = mesh.fill_small_holes(fm, np.inf) & ~fm
    n_gaps = ndi.label(gaps)[1]
    assert n_gaps == 2 and gaps.sum() > 2 * mesh.MIN_HOLE_AREA
    me = mesh.mesh_from_mask(fm)
    assert boundary_loop_count(me) == 3  # the outline and one loop per gap
    assert me.area == pytest.approx(fm.sum(), rel=0.05)
    ij = np.argwhere(ndi.binary_erosion(gaps, iterations=2))  # well inside the gaps
    assert len(ij) and not mesh.point_in_mesh(me, ij[:, ::-1].astype(float)).any()
    assert me.is_positively_oriented and me.min_angle() >= MIN_ANGLE_TOL
    # fill_holes=True: the old behaviour, meshed over
    filled = mesh.foreground_mask(img, fill_holes=True)
    assert np.array_equal(filled, fm | gaps)
    assert boundary_loop_count(mesh.mesh_from_mask(filled)) == 1
    # on paper (no alpha) holes are filled by default and kept on request
    from physlab.image import over_white, to_uint8

    paper = to_uint8(over_white(img))
    assert not (mesh.fill_small_holes(mesh.foreground_mask(paper), np.inf)
                & ~mesh.foreground_mask(paper)).any()
    kept = mesh.foreground_mask(paper, fill_holes=False)  # every hole: gaps and light fills
    kept_holes = mesh.fill_small_holes(kept, np.inf) & ~kept
    labels, _ = ndi.label(gaps)
    assert all((kept_holes & (labels == k)).any() for k in (1, 2))
    with pytest.raises(ValueError, match="fill_holes must be None"):
        mesh.foreground_mask(img, fill_holes="yes")


# ---------------------------------------------------------------------------------- point location
def test_locate_points_barycentrics_reproduce_points():
    m = mesh.disk_mesh((0.0, 0.0), 5.0, max_area=0.5)
    rng = np.random.default_rng(1)
    p = rng.uniform(-6, 6, (2000, 2))
    tri, bary = mesh.locate_points(m, p)
    inside = tri >= 0
    recon = np.einsum("mk,mkd->md", bary[inside], m.X[m.tris[tri[inside]]])
    np.testing.assert_allclose(recon, p[inside], atol=1e-10)
    np.testing.assert_allclose(bary[inside].sum(1), 1.0)
    assert bary[inside].min() >= -1e-9
    r = np.linalg.norm(p, axis=1)
    assert np.all(inside[r < 4.9]) and not np.any(inside[r > 5.0])
    np.testing.assert_array_equal(mesh.point_in_mesh(m, p), inside)
    t0, b0 = mesh.locate_points(m, m.X[m.tris[7]].mean(0))  # a single point
    assert t0 == 7 and np.allclose(b0, 1 / 3)


def test_locate_points_grid_analytic():
    m = mesh.grid_mesh(1, 1, 2.0, 2.0)  # triangles (0, 1, 3) and (0, 3, 2)
    tri, bary = mesh.locate_points(m, [[1.5, 0.5], [0.5, 1.5], [3.0, 1.0]])
    np.testing.assert_array_equal(tri, [0, 1, -1])
    np.testing.assert_allclose(bary[0], [0.25, 0.5, 0.25])


# ---------------------------------------------------------------------------------- real drawings
#: Measured IoU(foreground_mask(texture), mask.png) with the defaults (reference numbers).
REFERENCE_IOU = {"char1": 0.985, "char2": 0.936, "char3": 0.957, "char4": 0.911, "char5": 0.870,
                 "char6": 0.983}


@pytest.mark.parametrize("name", datasets.ANIMATED_DRAWINGS)
def test_real_drawing_mask_and_mesh(real_data, name):
    d = datasets.animated_drawing(name)
    gt = d.notes["mask"]
    fm = mesh.foreground_mask(d.image)  # textures are opaque photos: Otsu on luminance
    iou = (fm & gt).sum() / (fm | gt).sum()
    assert iou > 0.8
    assert iou == pytest.approx(REFERENCE_IOU[name], abs=0.01)
    for m in (gt, fm):
        body = mesh.mask_components(m)[0]
        me = mesh.mesh_from_mask(m)
        assert me.area == pytest.approx(body.sum(), rel=0.05)  # covers the mask area
        assert me.min_angle() >= MIN_ANGLE_TOL and me.is_positively_oriented
        assert 100 <= me.n_tris <= 2000
        # the mesh lies on the drawing (y down): triangle centroids fall on mask pixels
        ij = np.round(me.X[me.tris].mean(1)[:, ::-1]).astype(int)
        assert body[ij[:, 0], ij[:, 1]].mean() > 0.97
    # skeleton joints (all inside the provided mask) become mesh vertices
    joints = d.notes["skeleton"]["xy"]
    me = mesh.mesh_from_mask(gt, points=joints)
    assert np.all(mesh.vertex_indices(me, joints) >= 0)
    assert me.min_angle() >= MIN_ANGLE_TOL and me.is_positively_oriented
