"""Tests of physlab.viz.view3d: capsule-bone human, PyVista offscreen frames (or the
matplotlib fallback), red keypose / green trajectory pixels, GIF export, errors."""
import warnings

import numpy as np
import pytest

from physlab.motion import PARENTS, forward_kinematics
from physlab.motion.export import TPOSE_OFFSETS
from physlab.motion.skeleton import FOOT_JOINTS, euler_to_matrix
from physlab.viz import view3d

SIZE = (160, 128)       # (width, height): small frames keep the suite fast


def _walk(T=30, fps=20.0):
    """A walk-ish clip by forward kinematics: legs and arms swing in antiphase, knees bend,
    arms hang down, the root moves forward (+z) at 1.2 m/s and bobs; feet on y = 0."""
    t = np.arange(T) / fps
    ph = 2 * np.pi * 1.0 * t                                                  # 1 stride / s
    ang = np.zeros((T, 22, 3))                                                # "XZY" degrees
    ang[:, 1, 0], ang[:, 2, 0] = -25 * np.sin(ph), 25 * np.sin(ph)            # hips
    ang[:, 4, 0] = 5 + 30 * np.maximum(0, np.sin(ph + 1.2))                   # knees
    ang[:, 5, 0] = 5 + 30 * np.maximum(0, -np.sin(ph + 1.2))
    ang[:, 16, 1], ang[:, 17, 1] = -75, 75                                    # arms down
    ang[:, 16, 0], ang[:, 17, 0] = 20 * np.sin(ph), -20 * np.sin(ph)          # arm swing
    ang[:, 18, 0] = ang[:, 19, 0] = -15                                       # elbows
    R = euler_to_matrix(ang, "XZY")
    root = np.c_[np.zeros(T), 0.95 + 0.02 * np.cos(2 * ph), 1.2 * t]
    x = forward_kinematics(R, TPOSE_OFFSETS, PARENTS, root)
    x[..., 1] -= x[:, list(FOOT_JOINTS), 1].min()
    return x


@pytest.fixture(scope="module")
def walk():
    return _walk()


@pytest.fixture(scope="module")
def backend():
    name = view3d.resolve_backend("auto")
    print(f"\nview3d backend: {name} ({view3d._probe_pyvista()[1]})")
    return name


def _red(img):
    img = img.astype(int)
    return (img[..., 0] > 150) & (img[..., 1] < 70) & (img[..., 2] < 70)


def _green(img):
    img = img.astype(int)
    return (img[..., 1] > 140) & (img[..., 0] < 90) & (img[..., 2] < 90)


# ----------------------------------------------------------------------------- geometry


def test_capsule_arrays_analytic():
    """One capsule from the origin to (0, 0, 1), radius 0.1: points at distance r from the
    axis segment, unit outward normals, area close to 2πrL + 4πr²."""
    a, b, r = np.zeros((1, 3)), np.array([[0, 0, 1.0]]), np.array([0.1])
    P, N, tris = view3d.capsule_arrays(a, b, r, n_theta=48, n_phi=16)
    s = np.clip(P[:, 2], 0, 1)
    dist = np.linalg.norm(P - s[:, None] * [0, 0, 1], axis=1)                 # to the segment
    np.testing.assert_allclose(dist, 0.1, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0)
    e1, e2 = P[tris[:, 1]] - P[tris[:, 0]], P[tris[:, 2]] - P[tris[:, 0]]
    cross = np.cross(e1, e2)
    area = 0.5 * np.linalg.norm(cross, axis=1).sum()
    assert area == pytest.approx(2 * np.pi * 0.1 + 4 * np.pi * 0.01, rel=5e-3)
    # triangles wind outwards: face normal agrees with the supplied normals
    centre_normal = N[tris].mean(1)
    assert np.all(np.sum(cross * centre_normal, axis=1) > 0)


def test_capsule_segments_follow_the_bones(walk):
    a, b, r, joint = view3d.capsule_segments(walk)
    T = len(walk)
    assert a.shape == b.shape == (T, 24, 3) and r.shape == joint.shape == (24,)
    np.testing.assert_allclose(a[:, :21], walk[:, PARENTS[1:]])
    np.testing.assert_allclose(b[:, :21], walk[:, 1:])
    np.testing.assert_allclose(r[:21], view3d.BONE_RADII[1:])
    assert r[3 - 1] > r[20 - 1]                    # torso thicker than the forearm
    # fixed reference: vertex count of the 24 default capsules (16 around, 5 per hemisphere)
    P, _, tris = view3d.capsule_arrays(a[:2], b[:2], r)
    assert P.shape == (2, 24 * 162, 3) and tris.shape == (24 * 320, 3)
    # head capsule sits above the head joint, along neck -> head
    assert np.all(b[:, 21, 1] > walk[:, 15, 1] + 0.08)


def test_skeleton_meshes(walk, backend):
    if backend != "pyvista":
        pytest.skip("PyVista cannot render here; geometry is checked by capsule_arrays")
    m = view3d.skeleton_meshes(walk[0])
    body, ground = m["body"], m["ground"]
    assert body.n_points == 24 * 162 and body.n_cells == 24 * 320
    assert set(np.unique(body.cell_data["joint"])) == set(range(1, 22))
    # the ground plane lies under the feet, touching the lowest capsule
    gy = ground.points[:, 1]
    np.testing.assert_allclose(gy, gy[0])
    assert body.points[:, 1].min() == pytest.approx(gy[0], abs=2e-3)
    assert body.points[:, 1].max() > 1.5                                       # up is +y


# ----------------------------------------------------------------------------- rendering


def test_render_frames_or_fallback_figure(walk, backend):
    kp_frame = 10
    traj = {"left_foot": walk[:15, 10], "right_wrist": np.where(
        (np.arange(len(walk)) % 10 < 6)[:, None], walk[:, 21], np.nan)}     # NaN gaps
    if backend == "pyvista":
        frames = view3d.render_motion_pyvista(walk, keypose_frame=kp_frame, trajectories=traj,
                                              frames=[0, kp_frame, 20], size=SIZE)
        assert len(frames) == 3
        for f in frames:
            assert f.shape == (SIZE[1], SIZE[0], 3) and f.dtype == np.uint8
            assert f.std() > 10                                               # not blank
        # red keypose and green trajectory pixels, as in Sketch2Anim's figures
        assert _red(frames[1]).sum() > 100 and _green(frames[0]).sum() > 15
        plain = view3d.render_motion_pyvista(walk, frames=0, size=SIZE)       # single image
        assert plain.shape == (SIZE[1], SIZE[0], 3)
        assert _red(plain).sum() == 0 and _green(plain).sum() == 0
    else:
        from matplotlib.figure import Figure

        fig = view3d.plot_motion_matplotlib(walk, keypose_frame=kp_frame, trajectories=traj)
        assert isinstance(fig, Figure)


def test_strobe_image(walk, backend, tmp_path):
    img = view3d.strobe(walk, every=6, keypose_frame=12, trajectories={"right_wrist": walk[:, 21]},
                        size=SIZE)
    assert img.shape == (SIZE[1], SIZE[0], 3) and img.dtype == np.uint8
    assert _red(img).sum() > 30
    if backend == "pyvista":
        assert _green(img).sum() > 10


def test_matplotlib_fallback_always_works(walk):
    from matplotlib.figure import Figure

    fig = view3d.plot_motion_matplotlib(walk, frames=5, size=SIZE)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    # y up is the vertical axis and the aspect is equal (box aspect = data extents)
    zlo, zhi = ax.get_zlim()
    assert zlo <= walk[5, :, 1].min() and zhi >= walk[5, :, 1].max()
    ext = np.array([np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())])
    np.testing.assert_allclose(ax.get_box_aspect() / ax.get_box_aspect()[0], ext / ext[0],
                               rtol=1e-6)
    # the (x, y, z) -> (x, -z, y) map is a proper rotation (right-handed)
    M = view3d._to_mpl(np.eye(3))
    assert np.linalg.det(M) == pytest.approx(1.0)
    frames = view3d.render_motion(walk[:4], backend="matplotlib", size=SIZE, keypose_frame=2)
    assert len(frames) == 4 and frames[0].shape == (SIZE[1], SIZE[0], 3)
    assert _red(frames[2]).sum() > 20 and _red(frames[0]).sum() < _red(frames[2]).sum()


def test_auto_falls_back_with_one_warning(walk, monkeypatch):
    monkeypatch.setattr(view3d, "_probe_pyvista", lambda: (False, "forced by the test"))
    with pytest.warns(RuntimeWarning, match="forced by the test.*falls back to matplotlib"):
        img = view3d.strobe(walk, every=10, size=SIZE)
    assert img.shape == (SIZE[1], SIZE[0], 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                                        # warned once
        assert view3d.resolve_backend("auto") == "matplotlib"
    with pytest.raises(RuntimeError, match="cannot render offscreen"):
        view3d.resolve_backend("pyvista")


def test_gif_export(walk, tmp_path):
    import imageio.v3 as iio

    T = 8
    path = view3d.motion_to_gif(walk[:T], tmp_path / "walk.gif", fps=20, size=(96, 96),
                                keypose_frame=3)
    frames = iio.imread(path, index=None)
    assert frames.shape[:3] == (T, 96, 96)
    assert not list(tmp_path.glob(".*"))                                     # atomic, no temp
    html = view3d.show_motion(walk[:4], interactive=False, size=(64, 64))
    assert "base64" in html.data


# ----------------------------------------------------------------------------- errors


def test_errors(walk):
    with pytest.raises(ValueError, match=r"shape \(T, 22, 3\)"):
        view3d.render_motion(walk[:, :21], backend="matplotlib")
    bad = walk.copy()
    bad[3, 4, 0] = np.nan
    with pytest.raises(ValueError, match="NaN.*frame 3, joint left_knee"):
        view3d.strobe(bad, backend="matplotlib")
    with pytest.raises(ValueError, match="unknown joint 'left_hand'"):
        view3d.plot_motion_matplotlib(walk, trajectories={"left_hand": walk[:, 20]})
    with pytest.raises(ValueError, match="unknown trajectory joint 22"):
        view3d.plot_motion_matplotlib(walk, trajectories={22: walk[:, 20]})
    with pytest.raises(ValueError, match=r"trajectory of head must have shape \(t_r, 3\)"):
        view3d.plot_motion_matplotlib(walk, trajectories={"head": walk[:, 15, :2]})
    with pytest.raises(TypeError, match="trajectories must be a dict"):
        view3d.plot_motion_matplotlib(walk, trajectories=[walk[:, 20]])
    with pytest.raises(ValueError, match="no finite point"):
        view3d.plot_motion_matplotlib(walk, trajectories={"head": np.full((5, 3), np.nan)})
    with pytest.raises(ValueError, match=r"keypose must have shape \(22, 3\)"):
        view3d.plot_motion_matplotlib(walk, keypose=walk[0, :5])
    with pytest.raises(ValueError, match="keypose_frame must be an integer"):
        view3d.plot_motion_matplotlib(walk, keypose_frame=len(walk))
    with pytest.raises(ValueError, match="camera must be one of"):
        view3d.plot_motion_matplotlib(walk, camera="behind")
    with pytest.raises(ValueError, match="backend must be"):
        view3d.render_motion(walk, backend="opengl")
    with pytest.raises(ValueError, match="every must be an integer"):
        view3d.strobe(walk, every=0, backend="matplotlib")
    with pytest.raises(ValueError, match="frames must be"):
        view3d.render_motion(walk, frames=[0, 99], backend="matplotlib")
