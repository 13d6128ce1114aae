"""physlab.inbetween.skeleton: validation, forward kinematics, angle/length interpolation."""
import numpy as np
import pytest

from physlab.inbetween.skeleton import Skeleton, check_compatible, interpolate

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
