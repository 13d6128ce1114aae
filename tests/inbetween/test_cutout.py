"""Cut-out (paper-doll) posing of a drawing (physlab.inbetween.cutout)."""
import numpy as np
import pytest

from physlab.inbetween import Skeleton
from physlab.inbetween import cutout

RED, GREEN, BLUE = (255, 0, 0), (0, 160, 0), (0, 0, 255)


@pytest.fixture(scope="module")
def doll():
    """A torso block (red, x 20–40, y 15–65) with one horizontal arm (half-width 4 px):
    upper arm green from the shoulder (40, 25) to the elbow (70, 25), forearm blue to the
    hand (100, 25)."""
    names = ["root", "torso", "left_shoulder", "left_elbow", "left_hand"]
    rest = Skeleton(names, np.array([-1, 0, 1, 2, 3]),
                    np.array([[30, 60], [30, 20], [40, 25], [70, 25], [100, 25]], float))
    img = np.zeros((80, 120, 4), np.uint8)
    img[15:66, 20:41] = (*RED, 255)
    img[21:30, 41:70] = (*GREEN, 255)
    img[21:30, 70:106] = (*BLUE, 255)
    mask = img[..., 3] > 0
    widths = {"torso": 10.0, "left_shoulder": 10.0, "left_elbow": 4.0, "left_hand": 4.0}
    return img, mask, rest, widths


def _posed(rest, **xy):
    p = rest.xy.copy()
    for name, v in xy.items():
        p[rest.index(name)] = v
    return rest.with_xy(p)


def test_parts_and_segmentation_of_a_tiny_doll(doll):
    img, mask, rest, widths = doll
    groups = cutout.part_bones(rest)
    assert list(groups) == ["torso", "left_upper_arm", "left_forearm"]
    parts = cutout.segment_parts(mask, rest, widths)
    lab = parts.labels
    assert (lab[20:60, 22:38] == 0).all()           # torso block
    assert (lab[22:29, 45:67] == 1).all()           # upper arm
    assert (lab[22:29, 73:104] == 2).all()          # forearm with the hand beyond the wrist
    assert (lab[~mask] == -1).all() and (lab[mask] >= 0).all()
    assert parts.parent.tolist() == [-1, 0, 1]
    assert [rest.names[j] for j in parts.joint[1:]] == ["left_shoulder", "left_elbow"]
    # the elbow cap is a disc about as wide as the arm: upper-arm pixels next to the elbow
    assert 3.0 <= parts.cap_radius[2] <= 7.0
    assert parts.caps[2].sum() > 0 and (lab[parts.caps[2]] == 1).all()


def test_rest_pose_reproduces_the_drawing_exactly(doll):
    img, mask, rest, widths = doll
    parts = cutout.segment_parts(mask, rest, widths)
    out = cutout.render_cutout(img, parts, rest, rest)
    ref = img.astype(np.float32) / 255
    assert np.abs(out - ref).max() < 1e-6


def test_bent_elbow_moves_the_forearm_rigidly_and_the_cap_fills_the_corner(doll):
    """Forearm turned 90° clockwise on screen about the elbow: a 90° turn maps the pixel grid
    onto itself, so every forearm pixel lands exactly on its rotated place; the corner outside
    the bend is empty without caps and filled (upper-arm colour) with them."""
    img, mask, rest, widths = doll
    bent = _posed(rest, left_hand=(70, 55))
    T = cutout.part_transforms(cutout.segment_parts(mask, rest, widths), rest, bent)
    assert np.allclose(T[2, :, :2], [[0, -1], [1, 0]], atol=1e-12)
    for caps in (False, True):
        parts = cutout.segment_parts(mask, rest, widths, caps=caps)
        out = cutout.render_cutout(img, parts, rest, bent)
        for x, y in [(80, 27), (95, 22), (104, 29)]:   # rest forearm pixels
            X, Y = 70 - (y - 25), 25 + (x - 70)           # (dx, dy) -> (-dy, dx)
            assert np.allclose(out[Y, X], np.array([*BLUE, 255]) / 255, atol=1e-6)
        corner = out[21:24, 72:74, 3]    # outside the bend, past the upper arm (grown 1 px)
        if caps:
            assert corner.min() > 0.99
            assert np.allclose(out[22, 72, :3], np.array(GREEN) / 255, atol=1e-6)
        else:
            assert corner.max() == 0.0


@pytest.mark.parametrize("arm_nearer", [True, False])
def test_nearer_part_is_painted_over_the_farther(doll, arm_nearer):
    """The whole arm swung 180° about the shoulder lies across the torso block: it shows there
    when its joints are nearer than the torso's, the torso shows when they are farther."""
    img, mask, rest, widths = doll
    swung = _posed(rest, left_elbow=(10, 25), left_hand=(-20, 25))
    d = -1.0 if arm_nearer else 1.0
    swung = swung.with_depth([0.0, 0.0, 0.0, d, d])
    parts = cutout.segment_parts(mask, rest, widths)
    out = cutout.render_cutout(img, parts, rest, swung)
    want = GREEN if arm_nearer else RED
    assert np.allclose(out[25, 24:36, :3], np.array(want) / 255, atol=1e-6)
    layers = cutout.cutout_layers(img, parts, rest, swung)
    order = [n for n, kind, *_ in layers if kind == "part"]
    assert (order.index("left_upper_arm") > order.index("torso")) == arm_nearer


def test_bad_arguments(doll):
    img, mask, rest, widths = doll
    with pytest.raises(ValueError, match="mask must be a non-empty"):
        cutout.segment_parts(mask.astype(int), rest)
    with pytest.raises(TypeError, match="skeleton must be a Skeleton"):
        cutout.part_bones(None)
    with pytest.raises(ValueError, match="caps must be True or False"):
        cutout.segment_parts(mask, rest, caps="yes")
    with pytest.raises(ValueError, match="widths"):
        cutout.segment_parts(mask, rest, {"left_elbow": -1.0})
    parts = cutout.segment_parts(mask, rest, widths)
    with pytest.raises(ValueError, match="parts were cut from"):
        cutout.render_cutout(img[:40], parts, rest, rest)
