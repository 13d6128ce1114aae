"""physlab.inbetween.skeleton: validation, forward kinematics, interpolation methods."""
import numpy as np
import pytest

from physlab.inbetween.skeleton import (INTERPOLATION_METHODS, Skeleton, check_compatible,
                                       interpolate)

NAMES = ("root", "a", "b", "c")
PARENTS = np.array([-1, 0, 1, 0])


def arm(angle_b=0.0, length_b=10.0, root=(50.0, 50.0)):
    """root → a (10 px right) → b (bent by angle_b), root → c (down)."""
    return Skeleton.from_local(NAMES, PARENTS, root, [0, 0, angle_b, np.pi / 2],
                               [0, 10, length_b, 5])


def test_forward_kinematics_analytic():
    sk = arm(np.pi / 2)
    assert np.allclose(sk.xy, [[50, 50], [60, 50], [60, 60], [50, 55]])
    assert np.allclose(sk.bone_lengths(), [0, 10, 10, 5])
    assert np.allclose(sk.local_angles(), [0, 0, np.pi / 2, np.pi / 2])
    assert sk.bones.tolist() == [[0, 1], [1, 2], [0, 3]]
    # handles: joints then bone midpoints (paper Sec. 4.2)
    assert np.allclose(sk.handles()[4:], [[55, 50], [60, 55], [50, 52.5]])


def test_local_round_trip_random():
    rng = np.random.default_rng(0)
    for _ in range(20):
        sk = Skeleton.from_local(NAMES, PARENTS, rng.uniform(0, 100, 2),
                                 rng.uniform(-np.pi, np.pi, 4), rng.uniform(1, 20, 4))
        back = Skeleton.from_local(NAMES, PARENTS, sk.xy[0], sk.local_angles(),
                                   sk.bone_lengths())
        assert np.allclose(back.xy, sk.xy, atol=1e-9)


def test_interpolate_blends_angles_and_lengths_not_positions():
    s0, s1 = arm(0.0), arm(np.pi * 0.9)  # elbow swings by 162°
    mid = interpolate(s0, s1, 0.5)
    assert np.isclose(mid.local_angles()[2], np.pi * 0.45)
    assert np.isclose(mid.bone_lengths()[2], 10.0)  # joint-position blending would give 1.6 px
    assert interpolate(s0, s1, 0.0) is s0 and interpolate(s0, s1, 1.0) is s1
    seq = interpolate(s0, arm(0.0, 20.0, root=(70, 40)), np.linspace(0, 1, 5))
    assert np.allclose([s.bone_lengths()[2] for s in seq], [10, 12.5, 15, 17.5, 20])
    assert np.allclose(seq[2].xy[0], [60, 45])


def test_interpolate_takes_shortest_arc():
    s0, s1 = arm(np.radians(170)), arm(np.radians(-170))
    mid = interpolate(s0, s1, 0.5)
    assert np.isclose(abs(mid.local_angles()[2]), np.pi)  # through 180°, not through 0°


def test_zero_length_bone_inherits_angle():
    sk = Skeleton(("r", "h", "t"), [-1, 0, 1], [[10, 10], [10, 10], [10, 0]])
    assert np.isclose(sk.local_angles()[2], -np.pi / 2)
    back = Skeleton.from_local(sk.names, sk.parents, sk.xy[0], sk.local_angles(),
                               sk.bone_lengths())
    assert np.allclose(back.xy, sk.xy)


def test_animated_drawings_config(real_data):
    cfg = real_data / "animated_drawings/examples/characters/char1/char_cfg.yaml"
    sk = Skeleton.from_animated_drawings(cfg)
    assert len(sk) == 16 and sk.names[sk.root] == "root"
    assert np.allclose(sk.xy[sk.index("left_hand")], [449, 278])


@pytest.mark.parametrize("kwargs, match", [
    (dict(names=("a", "a"), parents=[-1, 0], xy=np.zeros((2, 2))), "unique"),
    (dict(names=("a", "b"), parents=[-1, -1], xy=np.zeros((2, 2))), "exactly one root"),
    (dict(names=("a", "b", "c"), parents=[-1, 2, 1], xy=np.zeros((3, 2))), "cycle"),
    (dict(names=("a", "b"), parents=[-1, 0], xy=np.zeros((3, 2))), "shape"),
    (dict(names=("a", "b"), parents=[-1, 0], xy=[[0, 0], [np.nan, 0]]), "NaN"),
    (dict(names=("a", "b"), parents=[-1, 5], xy=np.zeros((2, 2))), "parents"),
])
def test_bad_skeletons(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Skeleton(**kwargs)


def test_incompatible_skeletons():
    other = Skeleton(("root", "a", "b", "d"), PARENTS, arm().xy)
    with pytest.raises(ValueError, match="different joints"):
        interpolate(arm(), other, 0.5)
    reparented = Skeleton(NAMES, [-1, 0, 0, 0], arm().xy)
    with pytest.raises(ValueError, match="different topology"):
        check_compatible(arm(), reparented)
    with pytest.raises(ValueError, match="no joint"):
        arm().index("elbow")


# ------------------------------------------------------------------ interpolation methods
def random_pair(seed, equal_lengths=False):
    """Two random poses of the 4-joint arm (lengths differ unless ``equal_lengths``)."""
    rng = np.random.default_rng(seed)
    L = rng.uniform(2, 20, 4)
    return [Skeleton.from_local(NAMES, PARENTS, rng.uniform(0, 100, 2),
                                rng.uniform(-np.pi, np.pi, 4),
                                L if equal_lengths else rng.uniform(2, 20, 4))
            for _ in range(2)]


@pytest.mark.parametrize("method", INTERPOLATION_METHODS)
def test_every_method_returns_the_keys(method):
    s0, s1 = random_pair(1)
    seq = interpolate(s0, s1, [0.0, 0.3, 1.0], method=method)
    assert seq[0] is s0 and seq[2] is s1
    assert interpolate(s0, s1, 0.0, method=method) is s0
    assert interpolate(s0, s1, 1.0, method=method) is s1
    mid = seq[1]
    assert mid.same_topology(s0) and np.all(np.isfinite(mid.xy))
    # t just inside [0, 1] is continuous with the keys (no jump at the ends)
    near = interpolate(s0, s1, [1e-9, 1 - 1e-9], method=method)
    assert np.allclose(near[0].xy, s0.xy, atol=1e-6) and np.allclose(near[1].xy, s1.xy, atol=1e-6)


def test_positions_is_linear_in_the_joints():
    s0, s1 = random_pair(2)
    t = np.linspace(0, 1, 7)
    seq = interpolate(s0, s1, t, method="positions")
    for ti, s in zip(t, seq):
        assert np.allclose(s.xy, (1 - ti) * s0.xy + ti * s1.xy, atol=1e-12)
    # the 162° elbow swing of the angle test: the forearm shrinks to 1.6 px halfway
    mid = interpolate(arm(0.0), arm(np.pi * 0.9), 0.5, method="positions")
    assert np.isclose(mid.bone_lengths()[2], 10 * np.cos(np.pi * 0.45))


def test_global_angles_keep_equal_bone_lengths_and_match_local_for_small_turns():
    for seed in range(10):
        s0, s1 = random_pair(seed, equal_lengths=True)
        for s in interpolate(s0, s1, np.linspace(0, 1, 9), method="global_angles"):
            assert np.allclose(s.bone_lengths(), s0.bone_lengths(), atol=1e-9)
    # a 60° turn of the whole arm plus a 40° elbow bend: absolute and local blends agree
    # (FK is linear in the angles; they differ only in the branch of turns past 180°)
    s0, s1 = arm(0.0), Skeleton.from_local(NAMES, PARENTS, (50, 50),
                                           [0, np.pi / 3, np.radians(40), np.pi / 2],
                                           [0, 10, 10, 5])
    for t in (0.25, 0.5, 0.8):
        g = interpolate(s0, s1, t, method="global_angles")
        assert np.allclose(g.xy, interpolate(s0, s1, t).xy, atol=1e-9)
    # a bone whose summed turn exceeds 180°: global takes the other, shorter way round
    s0 = Skeleton.from_local(NAMES, PARENTS, (50, 50), [0, 0, 0, 0], [0, 10, 10, 5])
    s1 = Skeleton.from_local(NAMES, PARENTS, (50, 50), [0, np.radians(120),
                                                        np.radians(120), 0], [0, 10, 10, 5])
    g = interpolate(s0, s1, 0.5, method="global_angles").bone_angles()[2]
    loc = interpolate(s0, s1, 0.5).bone_angles()[2]
    assert np.isclose(_wrap_deg(g), -60) and np.isclose(_wrap_deg(loc), 120)


def _wrap_deg(a):
    return (np.degrees(a) + 180) % 360 - 180


@pytest.mark.parametrize("method", INTERPOLATION_METHODS)
def test_methods_are_symmetric_in_time(method):
    """Swapping the keys and t ↦ 1 − t gives the same skeletons (per-bone easing included)."""
    s0, s1 = random_pair(3)
    t = np.array([0.1, 0.25, 0.5, 0.7])
    fwd = interpolate(s0, s1, t, method=method)
    bwd = interpolate(s1, s0, 1 - t, method=method)
    for a, b in zip(fwd, bwd):
        assert np.allclose(a.xy, b.xy, atol=1e-9)


def test_eased_slows_bones_near_the_keys_and_keeps_the_middle():
    s0, s1 = arm(0.0), arm(np.pi / 2)
    mid = interpolate(s0, s1, 0.5, method="eased")
    assert np.allclose(mid.xy, interpolate(s0, s1, 0.5).xy)  # smoothstep(½) = ½
    q = interpolate(s0, s1, 0.25, method="eased")
    # smoothstep(¼) = 5/32: the elbow has turned 5/32 of 90°, not a quarter
    assert np.isclose(q.local_angles()[2], np.pi / 2 * 5 / 32)
    # the root still moves linearly
    s2 = arm(np.pi / 2, root=(70, 50))
    assert np.allclose(interpolate(s0, s2, 0.25, method="eased").xy[0], [55, 50])


def test_root_variants():
    # centroid: the joints' mean moves on its chord, the pose is local_angles'
    s0, s1 = random_pair(4)
    for t in (0.3, 0.5):
        c = interpolate(s0, s1, t, method="centroid")
        assert np.allclose(c.xy.mean(axis=0), (1 - t) * s0.xy.mean(0) + t * s1.xy.mean(0))
        assert np.allclose(c.bone_vectors(), interpolate(s0, s1, t).bone_vectors())
    # anchored: a joint that does not move between the keys stays put (a planted foot)
    s0 = arm(np.radians(-30), root=(50, 50))
    s1 = Skeleton.from_local(NAMES, PARENTS, (40, 48), [0, 0, 0, np.radians(80)],
                             [0, 10, 10, 5])
    s1 = s1.with_xy(s1.xy + (s0.xy[2] - s1.xy[2]))  # the hand b at the same place
    for t in (0.25, 0.5):
        a = interpolate(s0, s1, t, method="anchored")
        assert np.allclose(a.xy[2], s0.xy[2])
        assert np.allclose(a.bone_vectors(), interpolate(s0, s1, t).bone_vectors())


def test_interpolate_reference_numbers():
    s0, s1 = arm(0.0), arm(np.pi / 2, root=(60, 40))
    mid = {m: interpolate(s0, s1, 0.5, method=m).xy[2] for m in INTERPOLATION_METHODS}
    assert np.allclose(mid["local_angles"], [55 + 10 + 10 / np.sqrt(2), 45 + 10 / np.sqrt(2)])
    assert np.allclose(mid["global_angles"], mid["local_angles"])
    assert np.allclose(mid["positions"], [70, 50])  # b is at (70, 50) in both keys


def test_depths_are_blended_linearly_by_every_method():
    s0, s1 = random_pair(5)
    s0, s1 = s0.with_depth([0, 1, 2, 3]), s1.with_depth([2, 1, 0, 3])
    for m in INTERPOLATION_METHODS:
        assert np.allclose(interpolate(s0, s1, 0.25, method=m).depth, [0.5, 1, 1.5, 3])


def test_unknown_method_names_the_options():
    with pytest.raises(ValueError, match="unknown interpolation method 'slerp'.*local_angles.*"
                                         "positions"):
        interpolate(arm(), arm(1.0), 0.5, method="slerp")
