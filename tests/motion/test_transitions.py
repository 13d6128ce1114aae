"""Tests of physlab.motion.transitions: linear / slerp / SQUAD gap filling between two clips."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from physlab.motion import transitions
from physlab.motion.export import TPOSE_OFFSETS
from physlab.motion.skeleton import PARENTS, bone_lengths, euler_to_matrix, forward_kinematics
import functools

from physlab.motion.transitions import linear_transition, slerp_transition, squad_transition

ALL = [linear_transition, slerp_transition, squad_transition]
#: SQUAD with the context's angular velocities as tangents (C1): the variant whose
#: properties most tests below check; the default Shoemake tangents are tested at the end.
squad_c = functools.partial(squad_transition, tangents="context")
squad_c.__name__ = "squad_transition_context"
ROTATIONAL = [slerp_transition, squad_c]
L_SHOULDER, L_ELBOW = 16, 18


def _walk(T=90, fps=20, period=1.1, speed=1.3):
    """Walking-like rigid clip (T, 22, 3): sinusoidal local rotations (degrees, ZXY) of hips,
    knees, ankles, pelvis, spine, arms, a root moving forward (+z) at ``speed`` m/s with a
    vertical bob; gait cycle ``period`` s."""
    ph = 2 * np.pi * np.arange(T) / fps / period                     # (T,) gait phase
    s, c = np.sin(ph), np.cos(ph)
    ang = np.zeros((T, 22, 3))                                       # (T, 22, 3) Z, X, Y angles
    ang[:, 1, 1], ang[:, 2, 1] = 25 * s, -25 * s                     # hip flexion
    ang[:, 4, 1], ang[:, 5, 1] = -15 * (1 - c) - 5, -15 * (1 + c) - 5   # knees
    ang[:, 7, 1], ang[:, 8, 1] = 10 * c, -10 * c                     # ankles
    ang[:, 0, 0], ang[:, 0, 2] = 4 * s, 6 * s                        # pelvis roll, yaw
    ang[:, 3, 2], ang[:, 6, 1] = -5 * s, 3                           # spine counter-twist, lean
    ang[:, 16, 0], ang[:, 17, 0] = -70 + 5 * c, 70 - 5 * c           # arms down
    ang[:, 16, 2], ang[:, 17, 2] = 20 * s, 20 * s                    # arm swing
    ang[:, 18, 2], ang[:, 19, 2] = 15 + 10 * s, -15 + 10 * s         # elbows
    ang[:, 15, 1] = 5 * np.sin(2 * ph)                               # head nod
    root = np.c_[0.02 * s, 0.93 + 0.02 * np.cos(2 * ph), speed * np.arange(T) / fps]
    return forward_kinematics(euler_to_matrix(ang, "ZXY"), TPOSE_OFFSETS, PARENTS, root)


def _cut(x, start, n):
    """before (start frames), ground truth gap (n), after (rest)."""
    return x[:start], x[start:start + n], x[start + n:]


def _single_joint_clip(angles_deg, joint=L_SHOULDER, root=None):
    """T-pose with identity rotations except ``joint`` rotating about z by ``angles_deg`` (T,)."""
    T = len(angles_deg)
    ang = np.zeros((T, 22, 3))
    ang[:, joint, 0] = angles_deg
    root = np.tile([0.0, 0.95, 0.0], (T, 1)) if root is None else root
    return forward_kinematics(euler_to_matrix(ang, "ZXY"), TPOSE_OFFSETS, PARENTS, root)


def _spin_motion(rate=0.35, T=51):
    """The left upper arm swinging about z at ``rate`` rad/frame for T frames."""
    return _single_joint_clip(np.degrees(rate) * np.arange(T))


def _elbow_angle(x):
    """(T,) degrees, direction of the left upper arm in the (x, y) plane."""
    d = x[:, L_ELBOW] - x[:, L_SHOULDER]
    return np.degrees(np.arctan2(d[:, 1], d[:, 0]))


def _junction(before, fill, after):
    """Per-joint (velocity jump, step ratio) at the two junctions, and the clip's steps."""
    full = np.concatenate([before, fill, after])
    d = np.diff(full, axis=0)                                        # (T - 1, 22, 3) steps
    i0, i1 = len(before) - 1, len(before) + len(fill) - 1            # steps into / out of gap
    jumps = [np.linalg.norm(d[i0] - d[i0 - 1], axis=-1),             # (22,) each
             np.linalg.norm(d[i1] - d[i1 + 1], axis=-1)]
    step = np.linalg.norm(d, axis=-1)
    ratios = [step[i0] / step[i0 - 1], step[i1] / step[i1 + 1]]
    return jumps, ratios


# ----------------------------------------------------------------------------- analytic cases


def test_linear_transition_weights_k_over_n_plus_1():
    rng = np.random.default_rng(0)
    before, after = rng.normal(size=(3, 22, 3)), rng.normal(size=(4, 22, 3))
    out = linear_transition(before, after, 4)
    assert out.shape == (4, 22, 3) and out.dtype == np.float64
    for k in range(1, 5):
        assert np.allclose(out[k - 1], before[-1] + k / 5 * (after[0] - before[-1]))
    mid = linear_transition(before[-1:], after[:1], 1)               # 1-frame contexts suffice
    assert np.allclose(mid[0], (before[-1] + after[0]) / 2)


@pytest.mark.parametrize("fn", ALL)
def test_constant_pose_gives_the_constant_pose(fn):
    pose = np.random.default_rng(1).normal(scale=0.3, size=(22, 3))  # any pose, not T-pose
    clip = np.broadcast_to(pose, (5, 22, 3))
    out = fn(clip, clip, 7)
    assert out.shape == (7, 22, 3)
    assert np.abs(out - pose).max() < 1e-9


@pytest.mark.parametrize("fn", ROTATIONAL)
def test_uniform_rotation_of_one_joint_is_continued_at_constant_angular_velocity(fn):
    angles = 10.0 + 4.0 * np.arange(40)                              # 4°/frame, up to 166°
    before, truth, after = _cut(_single_joint_clip(angles), 10, 20)
    out = fn(before, after, 20)
    assert np.abs(out - truth).max() < 1e-9                          # every joint, exactly
    assert np.allclose(np.diff(_elbow_angle(out)), 4.0)
    # the chord of linear interpolation cuts the arc: the upper arm shrinks, angles are off
    lin = linear_transition(before, after, 20)
    assert np.abs(lin - truth).max() > 0.05
    upper_arm = bone_lengths(lin)[:, L_ELBOW - 1]                    # (20,) rest length 0.26 m
    assert upper_arm.min() < 0.26 - 0.02


def test_slerp_angles_are_linear_squad_follows_the_context_velocity():
    # the upper arm turns at 2°/frame before the gap and 6°/frame after it
    n = 9
    a_before = 20.0 + 2.0 * np.arange(-4, 1)                         # ends at 20°
    a_after = 70.0 + 6.0 * np.arange(4)                              # starts at 70°
    before, after = _single_joint_clip(a_before), _single_joint_clip(a_after)
    h = np.arange(1, n + 1) / (n + 1)
    slerp_angles = _elbow_angle(slerp_transition(before, after, n))
    assert np.allclose(slerp_angles, 20.0 + 50.0 * h)                # the geodesic, uniformly
    # naive 1D SQUAD (all rotations about z commute, so quaternion logs add as angles)
    a0, a1, m0, m1 = 20.0, 70.0, (n + 1) * 2.0, (n + 1) * 6.0
    s0, s1 = a0 + (m0 - (a1 - a0)) / 2, a1 - (m1 - (a1 - a0)) / 2
    u = 2 * h * (1 - h)
    naive = (1 - u) * (a0 + h * (a1 - a0)) + u * (s0 + h * (s1 - s0))
    squad_angles = _elbow_angle(squad_c(before, after, n))
    assert np.allclose(squad_angles, naive)
    assert abs(squad_angles[0] - 20.0 - 2.0) < 0.5                   # first step ≈ 2°, not 5°
    assert abs(70.0 - squad_angles[-1] - 6.0) < 0.5                  # last step ≈ 6°, not 5°


def test_slerp_pelvis_rotation_is_the_scipy_geodesic():
    rng = np.random.default_rng(2)
    R0, R1 = Rotation.from_rotvec([0.3, 0.5, -0.2]), Rotation.from_rotvec([-0.4, 1.6, 0.5])
    n, h = 6, np.arange(1, 7) / 7
    p0, p1 = np.array([0.1, 0.9, 0.0]), np.array([0.5, 0.95, 0.8])

    def clip(G, root, T):
        R = np.broadcast_to(np.eye(3), (T, 22, 3, 3)).copy()
        R[:, 0] = G.as_matrix()
        return forward_kinematics(R, TPOSE_OFFSETS, PARENTS, np.tile(root, (T, 1)))

    wobble = Rotation.from_rotvec(rng.normal(scale=0.1, size=3))     # context motion ignored
    before = np.concatenate([clip(wobble * R0, p0 - 0.05, 1), clip(R0, p0, 1)])
    after = np.concatenate([clip(R1, p1, 1), clip(R1 * wobble, p1 + 0.05, 1)])
    G = Slerp([0, 1], Rotation.concatenate([R0, R1]))(h).as_matrix()  # (n, 3, 3) geodesic
    R = np.broadcast_to(np.eye(3), (n, 22, 3, 3)).copy()
    R[:, 0] = G
    expected = forward_kinematics(R, TPOSE_OFFSETS, PARENTS, p0 + h[:, None] * (p1 - p0))
    assert np.abs(slerp_transition(before, after, n) - expected).max() < 1e-9
    # SQUAD uses the context velocities, so it leaves the geodesic
    assert np.abs(squad_c(before, after, n) - expected).max() > 1e-3


def test_turning_through_180_degrees_takes_the_short_way():
    # a character turning on the spot at 4°/frame through heading 180° (quaternion w = 0)
    T, yaw = 30, np.radians(120.0 + 4.0 * np.arange(30))
    R = np.broadcast_to(np.eye(3), (T, 22, 3, 3)).copy()
    R[:, 0] = Rotation.from_rotvec(yaw[:, None] * [0.0, 1.0, 0.0]).as_matrix()
    root = np.c_[np.zeros(T), np.full(T, 0.95), 0.05 * np.arange(T)]
    before, truth, after = _cut(forward_kinematics(R, TPOSE_OFFSETS, PARENTS, root), 10, 10)
    for fn in ROTATIONAL:
        assert np.abs(fn(before, after, 10) - truth).max() < 1e-9


@pytest.mark.parametrize("fn", ROTATIONAL)
def test_result_does_not_depend_on_quaternion_signs(fn, monkeypatch):
    before, _, after = _cut(_walk(T=40), 15, 8)
    reference = fn(before, after, 8)
    to_quat = transitions._quat_from_matrix
    rng = np.random.default_rng(3)

    def random_signs(R):                                             # q and -q: same rotation
        q = to_quat(R)
        return q * rng.choice([-1.0, 1.0], size=q.shape[:-1] + (1,))

    monkeypatch.setattr(transitions, "_quat_from_matrix", random_signs)
    assert np.abs(fn(before, after, 8) - reference).max() < 1e-9


def test_squad_inner_points_reduce_to_shoemake_for_even_keys():
    rng = np.random.default_rng(4)
    q = Rotation.from_rotvec(rng.normal(scale=0.6, size=(4, 5, 3))).as_quat()   # keys -1..2
    qm, q0, q1, q2 = np.roll(q, 1, axis=-1)                          # (5, 4) each, (w, x, y, z)
    log, mul, inv = transitions._qlog, transitions._qmul, transitions._qconj
    # Catmull-Rom tangents for unit key spacing
    m0 = (log(mul(inv(q0), q1)) - log(mul(inv(q0), qm))) / 2
    m1 = (log(mul(inv(q1), q2)) - log(mul(inv(q1), q0))) / 2
    s0, s1 = transitions._squad_inner_points(q0, q1, m0, m1)
    exp = transitions._qexp                                          # Shoemake 1987, s_i
    sh0 = mul(q0, exp(-(log(mul(inv(q0), q1)) + log(mul(inv(q0), qm))) / 4))
    sh1 = mul(q1, exp(-(log(mul(inv(q1), q2)) + log(mul(inv(q1), q0))) / 4))
    assert np.allclose(s0, sh0) and np.allclose(s1, sh1)
    # the squad curve interpolates the keys and has tangent m0 at h = 0 (finite difference)
    ends = transitions._squad(q0, q1, s0, s1, np.array([0.0, 1.0]))
    assert np.allclose(np.abs(np.sum(ends[0] * q0, -1)), 1) and \
        np.allclose(np.abs(np.sum(ends[1] * q1, -1)), 1)
    eps = 1e-6
    qe = transitions._squad(q0, q1, s0, s1, np.array([eps]))[0]
    assert np.allclose(log(mul(inv(q0), qe)) / eps, m0, atol=1e-4)


# ----------------------------------------------------------------------------- root


def test_hermite_root_reproduces_constant_velocity():
    x = _walk(T=60)                                                  # root bobs; make it straight
    v = np.array([0.03, 0.0, 0.065])
    x = x - x[:, :1] + (np.array([0.0, 0.93, 0.0]) + np.arange(60)[:, None] * v)[:, None]
    before, truth, after = _cut(x, 20, 20)
    assert np.abs(squad_c(before, after, 20)[:, 0] - truth[:, 0]).max() < 1e-12


def test_hermite_root_matches_the_cubic_with_context_velocities():
    pose = _walk(T=1)[0]
    pose = pose - pose[0]                                            # relative to the pelvis
    p0, v0 = np.array([0.0, 0.9, 0.0]), np.array([0.0, 0.0, 0.05])
    p1, v1 = np.array([1.0, 0.9, 0.6]), np.array([0.07, 0.0, 0.0])
    before = pose + np.stack([p0 - v0, p0])[:, None]
    after = pose + np.stack([p1, p1 + v1])[:, None]
    n = 11
    h = (np.arange(1, n + 1) / (n + 1))[:, None]
    cubic = ((2 * h**3 - 3 * h**2 + 1) * p0 + (h**3 - 2 * h**2 + h) * (n + 1) * v0
             + (-2 * h**3 + 3 * h**2) * p1 + (h**3 - h**2) * (n + 1) * v1)
    out = squad_c(before, after, n)
    assert np.abs(out[:, 0] - cubic).max() < 1e-12
    assert np.abs(out - (pose + cubic[:, None])).max() < 1e-9        # pose carried along
    lin = slerp_transition(before, after, n)[:, 0]                   # the simpler variant
    assert np.allclose(lin, p0 + h * (p1 - p0))


# ----------------------------------------------------------------------------- invariants


@pytest.mark.parametrize("fn", ALL)
def test_endpoints_continue_the_context(fn):
    x = _walk()
    before, _, after = _cut(x, 30, 20)
    out = fn(before, after, 20)
    max_step = np.linalg.norm(np.diff(x, axis=0), axis=-1).max()     # largest step in the clip
    assert np.linalg.norm(out[0] - before[-1], axis=-1).max() < 1.5 * max_step
    assert np.linalg.norm(after[0] - out[-1], axis=-1).max() < 1.5 * max_step


def test_bone_lengths_constant_for_rotational_methods_not_for_linear():
    x = _walk()
    before, _, after = _cut(x, 30, 20)
    true_lengths = bone_lengths(x[:1])[0]                            # (21,) rigid input
    for fn in ROTATIONAL:
        bl = bone_lengths(fn(before, after, 20))                     # (20, 21)
        assert np.abs(bl - true_lengths).max() < 1e-9
    lin = bone_lengths(linear_transition(before, after, 20))
    assert np.abs(lin - true_lengths).max() > 3e-4                   # chords shorten bones


def test_squad_is_c1_at_the_junctions_linear_and_slerp_are_not():
    x = _walk()
    before, _, after = _cut(x, 30, 20)
    max_acc = np.linalg.norm(np.diff(x, 2, axis=0), axis=-1).max()   # largest velocity change
    jumps, ratios = _junction(before, squad_c(before, after, 20), after)
    for jump, ratio in zip(jumps, ratios):
        assert jump.max() < 0.6 * max_acc                            # ≈ 0.37 measured
        assert np.all((ratio > 1 / 1.5) & (ratio < 1.5))             # 0.84 .. 1.13 measured
    for fn in (linear_transition, slerp_transition):                 # velocity jumps
        jumps, ratios = _junction(before, fn(before, after, 20), after)
        for jump, ratio in zip(jumps, ratios):
            assert jump.max() > 1.5 * max_acc                        # ≈ 2.2 measured
            assert np.any((ratio < 1 / 1.5) | (ratio > 1.5))         # 0.47 .. 1.88 measured


def test_match_ends_joins_a_non_rigid_context():
    x = _walk()
    y = x.copy()                                                     # after: 10 % larger bones
    for j in range(1, 22):
        y[:, j] = y[:, PARENTS[j]] + 1.1 * (x[:, j] - x[:, PARENTS[j]])
    before, after = x[:30], y[50:]
    rigid_jump = max(j.max() for j in _junction(x[:30], squad_c(x[:30], x[50:], 20),
                                                x[50:])[0])
    loose = squad_c(before, after, 20)
    matched = squad_c(before, after, 20, match_ends=True)
    jump_loose = max(j.max() for j in _junction(before, loose, after)[0])
    jump_matched = max(j.max() for j in _junction(before, matched, after)[0])
    assert jump_matched < 2 * rigid_jump < jump_loose                # 1.4x, 4.5x measured
    assert np.ptp(bone_lengths(loose), axis=0).max() < 1e-9          # default: rigid output
    assert np.ptp(bone_lengths(matched), axis=0).max() > 1e-3


# ----------------------------------------------------------------------------- real-looking gap


def _gap_errors(period=1.1, n=20):
    """Mean per-joint position error (m) of the three fills over every gap phase of a gait
    cycle: (phases, 4) for linear, slerp, squad (context tangents), squad (Shoemake's);
    10 context frames on each side."""
    x = _walk(T=100, period=period)
    errs = []
    for start in range(20, 20 + int(round(20 * period))):
        before, truth, after = x[start - 10:start], x[start:start + n], x[start + n:start + n + 10]
        errs.append([np.linalg.norm(fn(before, after, n) - truth, axis=-1).mean()
                     for fn in (linear_transition, slerp_transition, squad_c, squad_transition)])
    return np.array(errs)


def test_squad_beats_linear_on_a_walking_gap():
    errs = _gap_errors()                                             # (22, 4)
    mean = errs.mean(axis=0)
    assert mean[2] < 0.9 * mean[0]                                   # C1 squad < linear
    assert np.mean(errs[:, 2] < errs[:, 0]) > 0.9                    # for nearly every phase
    # fixed reference numbers (metres): linear, slerp, squad (context), squad (Shoemake):
    # Shoemake's tangents forget the context's velocity, so they do no better than linear
    assert np.allclose(mean, [0.1144591, 0.1144935, 0.0990218, 0.1153618], atol=1e-6)


# ----------------------------------------------------------------------------- errors


@pytest.mark.parametrize("fn", ALL)
@pytest.mark.parametrize("before, after, n, match", [
    (np.zeros((5, 21, 3)), np.zeros((5, 22, 3)), 3, "before must have shape"),
    (np.zeros((5, 22, 3)), np.zeros((22, 3)), 3, "after must have shape"),
    (np.zeros((5, 22, 3)), np.full((5, 22, 3), np.nan), 3, "after contains NaN"),
    (np.zeros((5, 22, 3)), np.zeros((5, 22, 3)), 0, "n must be >= 1"),
    (np.zeros((5, 22, 3)), np.zeros((5, 22, 3)), 2.5, "n must be an integer"),
    (np.zeros((5, 22, 3)), np.zeros((5, 22, 3)), True, "n must be an integer"),
    (np.zeros((0, 22, 3)), np.zeros((5, 22, 3)), 3, "before needs at least"),
])
def test_bad_input_raises(fn, before, after, n, match):
    with pytest.raises(ValueError, match=match):
        fn(before, after, n)


def test_squad_needs_two_context_frames_on_each_side():
    x = _walk(T=10)
    with pytest.raises(ValueError, match="before needs at least 2 frames"):
        squad_transition(x[:1], x[5:], 3)
    with pytest.raises(ValueError, match="after needs at least 2 frames"):
        squad_transition(x[:3], x[9:], 3)
    assert slerp_transition(x[:1], x[9:], 3).shape == (3, 22, 3)     # slerp needs only one


def test_default_shoemake_tangents_are_the_literal_formula_and_do_not_flip():
    """Shoemake's inner points on the four keys (as if evenly spaced), checked against the
    formula written out; on a joint spinning fast (0.35 rad/frame, as a generated wrist can)
    the context tangents (x 21) pass π and the curve jumps, Shoemake's do not."""
    from physlab.motion import transitions as tr

    rng = np.random.default_rng(4)
    q = rng.normal(size=(4, 22, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    qm, q0, q1, q2 = q
    L = lambda a, b: tr._qlog(tr._qmul(tr._qconj(a), b))               # noqa: E731
    s0 = tr._qmul(q0, tr._qexp(-(L(q0, q1) + L(q0, qm)) / 4))
    s1 = tr._qmul(q1, tr._qexp(-(L(q1, q2) + L(q1, q0)) / 4))
    m0, m1 = (L(q0, q1) - L(q0, qm)) / 2, (L(q1, q2) - L(q1, q0)) / 2
    g0, g1 = tr._squad_inner_points(q0, q1, m0, m1)
    same = lambda a, b: np.minimum(np.abs(a - b).max(-1), np.abs(a + b).max(-1))  # noqa: E731
    assert same(g0, s0).max() < 1e-9 and same(g1, s1).max() < 1e-9
    # a forearm spinning about its own axis fast in the context, pose otherwise still
    x = _spin_motion(rate=0.35)
    before, after = x[:10], x[31:]
    step = lambda y: np.linalg.norm(np.diff(y, axis=0), axis=-1).max()   # noqa: E731
    ctx = step(np.concatenate([before, squad_c(before, after, 20), after]))
    default = step(np.concatenate([before, squad_transition(before, after, 20), after]))
    assert default < 0.5 * ctx
    with pytest.raises(ValueError, match="tangents"):
        squad_transition(before, after, 20, tangents="catmull")
