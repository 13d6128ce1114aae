"""Tests of physlab.viz.storyboard_view: frame views, contact sheet, overlay frames, export,
BVH check. One example animation (3 frames, 160 frames) is generated per module (~3 s)."""
import dataclasses
import json
import warnings
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from physlab.motion.bvh import BVHMotion, read_bvh, write_bvh
from physlab.motion.camera import Camera, to_pixels
from physlab.motion.export import joints_to_bvh, joints_to_bvh_motion
from physlab.motion.skeleton import JOINT_NAMES, KINEMATIC_CHAINS, PARENTS
from physlab.motion.storyboard import (
    Storyboard,
    StoryboardFrame,
    animate_storyboard,
)
from physlab.viz.storyboard_view import (
    DEFAULT_CAMERA,
    EXPORT_FILES,
    EXPORT_FORMATS,
    check_bvh,
    export_storyboard,
    frame_camera,
    frame_view,
    overlay_pixel,
    resample_frames,
    sketch_overlay_frames,
    storyboard_contact_sheet,
)

EXAMPLE = Path(__file__).resolve().parents[2] / "data" / "motion" / "example_storyboard.json"
BLUE = np.array([31, 119, 180])
BVH_WARNING = "ignore:the BVH reproduces the joints only:UserWarning"


@pytest.fixture(scope="module")
def board():
    return Storyboard.load(EXAMPLE)


@pytest.fixture(scope="module")
def anim(board):
    import torch

    torch.set_num_threads(1)
    return animate_storyboard(board, steps=20, guidance_final=0)


@pytest.fixture(scope="module")
def overlay(board, anim):
    return sketch_overlay_frames(board, anim)


def _mask(img, color, tol=40):
    """Pixels of ``color`` (RGB 0..255, within ``tol``)."""
    return np.linalg.norm(img[..., :3].astype(float) - color, axis=-1) <= tol


def _count(img, color, tol=40):
    return int(_mask(img, color, tol).sum())


def _near(img, color, xy, radius, tol=40):
    """Number of pixels of ``color`` within ``radius`` px of the point ``xy`` = (x, y)."""
    H, W = img.shape[:2]
    yy, xx = np.mgrid[0:H, 0:W]
    return int((_mask(img, color, tol) & (np.hypot(xx - xy[0], yy - xy[1]) <= radius)).sum())


def _without_sketch(board):
    """The example with frame 0 as plain 2D conditions (the same ones, no sketch)."""
    f = board.frames[0]
    g = StoryboardFrame(f.action, keypose_2d=f.keypose_2d, trajectories_2d=f.trajectories_2d,
                        camera=f.camera, keypose_at=f.keypose_at)
    return Storyboard([g] + board.frames[1:], camera=board.camera, title=board.title)


# ----------------------------------------------------------------------------- frame views


def test_frame_views_kinds_cameras_and_frames(board, anim):
    views = [frame_view(board, anim, i) for i in range(len(board))]
    assert [v.kind for v in views] == ["sketch", "text", "text"]
    assert views[0].canvas == (480, 400) and views[0].y_down and views[0].units == "px"
    assert views[0].key_frame == 0 and views[1].key_frame is None
    # text frames fall back to the storyboard camera, without one to the 3/4 default
    assert frame_camera(board, 1) == board.camera
    bare = Storyboard([StoryboardFrame("a person jumps")])
    assert frame_camera(bare, 0) == DEFAULT_CAMERA == Camera(pitch=15, yaw=30)
    # every animation frame belongs to exactly one view: transitions go with the next clip
    covered = np.concatenate([list(v.frames) for v in views])
    np.testing.assert_array_equal(covered, np.arange(len(anim.joints)))
    assert [k for k in range(len(anim.joints)) if anim.frame_at(k) == 1] == list(views[1].frames)
    for i, v in enumerate(views):                                # the clip, and its bounds
        assert v.motion.shape == (len(range(160)[anim.segments[i]]), 22, 2)
        x0, x1, y0, y1 = v.bounds
        assert (v.motion[..., 0].min() >= x0 and v.motion[..., 0].max() <= x1
                and v.motion[..., 1].min() >= y0 and v.motion[..., 1].max() <= y1)
        assert x1 - x0 >= 1.2 * (y1 - y0) - 1e-9                 # at least a card's width
    with pytest.raises(IndexError, match="out of range"):
        frame_view(board, anim, 3)


def test_sketch_view_is_the_conditions_view_in_canvas_pixels(board, anim):
    """Invariant: the same frame drawn as a sketch (pixels) and as its 2D conditions
    (normalised units) differ only by the sketch's pixel frame, for the drawing and the
    motion alike."""
    px = frame_view(board, anim, 0)
    uv = frame_view(_without_sketch(board), anim, 0)
    assert uv.kind == "conditions" and not uv.y_down and uv.origin is None
    np.testing.assert_allclose(to_pixels(uv.motion, px.origin, px.pixels_per_unit), px.motion,
                               atol=1e-9)
    chains = to_pixels(np.concatenate(uv.pose), px.origin, px.pixels_per_unit)
    joints = board.frames[0].sketch.joints
    np.testing.assert_allclose(chains, joints[np.concatenate(KINEMATIC_CHAINS)], atol=1e-2)
    # the keypose frame of the clip starts near the drawn figure (conditioned generation)
    assert np.linalg.norm(px.motion[0] - joints, axis=1).mean() < 40          # px


def test_mismatched_animation_is_an_error(board, anim):
    short = dataclasses.replace(anim, segments=anim.segments[:2], placements=anim.placements[:2])
    with pytest.raises(ValueError, match="2 clips .* 3 frames"):
        storyboard_contact_sheet(board, short)
    with pytest.raises(TypeError, match="StoryboardAnimation"):
        sketch_overlay_frames(board, anim.joints)


# ----------------------------------------------------------------------------- contact sheet


def test_contact_sheet_axes_size_and_png(board, anim, tmp_path):
    path = tmp_path / "sheet" / "s.png"
    fig = storyboard_contact_sheet(board, anim, path=path)
    n = len(board)
    assert len(fig.axes) == 2 * n + 2
    np.testing.assert_allclose(fig.get_size_inches(), (10.2, 6.8))           # reference
    assert fig.axes[0].yaxis_inverted() and not fig.axes[2].yaxis_inverted()  # y down / up
    assert "a person walks" in fig.axes[0].get_title()
    for ax in fig.axes:
        assert ax.get_aspect() == 1.0
    for ax in fig.axes[1::2][:n] + fig.axes[-2:]:
        assert ax.get_xlabel() and ax.get_ylabel()
    img = iio.imread(path)
    assert img.shape[:2] == (680, 1020)
    assert not list(tmp_path.glob("sheet/.*"))                               # no temp left
    # pixels: the sketch panel holds the red trajectory stroke, the text cards none, the
    # result panels blue stick figures
    H = img.shape[0]

    def crop(ax):
        b = ax.get_window_extent()
        return img[int(H - b.y1):int(H - b.y0), int(b.x0):int(b.x1), :3]

    red = np.array([220, 0, 0])
    assert _count(crop(fig.axes[0]), red) > 100
    assert _count(crop(fig.axes[2]), red) == 0
    for i in range(n):
        assert _count(crop(fig.axes[2 * i + 1]), BLUE, tol=60) > 200


def test_contact_sheet_every(board, anim):
    def blue_collections(every):
        fig = storyboard_contact_sheet(board, anim, every=every)
        ax = fig.axes[1]                                         # clip 1, 40 frames
        return sum(1 for c in ax.collections
                   if np.allclose(c.get_edgecolor()[0][:3], BLUE / 255, atol=0.01))

    assert blue_collections(10) == 5                             # frames 0, 10, 20, 30, 39
    assert blue_collections(13) == 4                             # 0, 13, 26, 39
    with pytest.raises(ValueError, match="every must be an integer >= 1"):
        storyboard_contact_sheet(board, anim, every=0)


# ----------------------------------------------------------------------------- overlay frames


def test_overlay_shape_and_pose_pixels(board, anim, overlay):
    frames = overlay                      # its speed: benchmarks/bench_motion.py
    N = len(anim.joints)
    assert frames.shape == (N, 320, 320, 3) and frames.dtype == np.uint8
    for k in (0, 25, 50, 75, 130, N - 1):
        for j in (0, 15):                                        # pelvis dot, head circle
            xy = overlay_pixel(board, anim, k, joint=j)
            assert 0 <= xy[0] < 320 and 0 <= xy[1] < 320
            assert _near(frames[k], BLUE, xy, 4) >= 3, (k, j)
        far = overlay_pixel(board, anim, k) + (140, 0)           # far to the side: nothing
        assert _near(frames[k], BLUE, far, 10) == 0
    # the figure moves, the drawing does not
    assert not np.array_equal(frames[10], frames[30])
    assert _count(frames[0], np.array([220, 0, 0])) > 50         # the sketch's stroke
    assert _count(frames[100], np.array([220, 0, 0])) == 0       # a text-only frame
    assert (frames[:, :20].min(axis=(1, 2, 3)) < 150).all()      # header text, every frame


def test_overlay_places_the_pose_on_the_canvas(board, anim, overlay):
    """Independent of the library's fit: find the drawn canvas border in the picture, map the
    sketch-pixel pelvis through it and find the blue pelvis there."""
    frames = overlay
    sk = board.frames[0].sketch
    origin, ppu = sk.pixel_frame(*sk.trajectories_px())
    f = frames[0].astype(int)
    grey = (f[..., 0] == f[..., 1]) & (f[..., 1] == f[..., 2]) & (f[..., 0] >= 200) & \
        (f[..., 0] <= 245)                                # the light grey border, antialiased
    rows, cols = np.flatnonzero(grey.sum(1) > 100), np.flatnonzero(grey.sum(0) > 100)
    y0, y1, x0, x1 = rows.min(), rows.max(), cols.min(), cols.max()
    assert (x1 - x0) / (y1 - y0) == pytest.approx(480 / 400, rel=0.03)
    for k in (0, 20, 39):
        pelvis_px = to_pixels(sk.camera.project(anim.local(0)[k, 0]), origin, ppu)
        xy = (x0 + pelvis_px[0] / 480 * (x1 - x0), y0 + pelvis_px[1] / 400 * (y1 - y0))
        assert _near(frames[k], BLUE, xy, 4) >= 3, k


def test_overlay_size_and_errors(board, anim):
    small = sketch_overlay_frames(board, anim, size=(200, 120))
    assert small.shape == (len(anim.joints), 120, 200, 3)
    with pytest.raises(ValueError, match="at least"):
        sketch_overlay_frames(board, anim, size=(32, 32))


# ----------------------------------------------------------------------------- export


@pytest.mark.filterwarnings(BVH_WARNING)
def test_export_everything(board, anim, tmp_path):
    folder = tmp_path / "a" / "b"                                        # created
    out = export_storyboard(board, anim, folder)
    N = len(anim.joints)
    assert list(out) == list(EXPORT_FORMATS)
    assert {f: p.name for f, p in out.items()} == EXPORT_FILES
    assert all(p.parent == folder and p.stat().st_size > 0 for p in out.values())
    assert sorted(q.name for q in folder.iterdir()) == sorted(EXPORT_FILES.values())
    assert iio.imread(out["gif"], index=None).shape[0] == N
    sketch_gif = iio.imread(out["sketch_gif"], index=None)
    assert sketch_gif.shape[:3] == (N, 320, 320)
    import imageio_ffmpeg

    assert imageio_ffmpeg.count_frames_and_secs(str(out["mp4"]))[0] == N
    assert json.loads(out["json"].read_text()) == board.to_dict()
    assert Storyboard.load(out["json"]).to_dict() == board.to_dict()
    assert iio.imread(out["png"]).shape[:2] == (680, 1020)
    info = check_bvh(out["bvh"], n_frames=N, fps=20)
    assert info["n_frames"] == N


def test_export_errors(board, anim, tmp_path):
    with pytest.raises(ValueError, match=r"\['webm'\].*'bvh', 'gif', 'mp4', 'sketch_gif'"):
        export_storyboard(board, anim, tmp_path / "x", formats=("json", "webm"))
    assert not (tmp_path / "x").exists()
    with pytest.raises(ValueError, match="fps must be a number > 0"):
        export_storyboard(board, anim, tmp_path / "x", formats=("json",), fps=0)
    out = export_storyboard(board, anim, tmp_path / "y", formats="json")     # one name
    assert list(out) == ["json"]


def test_resample_frames_keeps_the_duration_and_linear_motion():
    """A motion linear in time resamples exactly, first and last frames kept; the nearest
    indices pick the closest input frame; the same rate is the identity."""
    t = np.arange(21.0)
    x = np.stack([t, 2 * t, -t], axis=-1)[:, None] * np.ones((1, 22, 1))    # (21, 22, 3)
    y, near = resample_frames(x, 20, 30)
    assert y.shape == (31, 22, 3)
    np.testing.assert_allclose(y[:, 0, 0], np.linspace(0, 20, 31), atol=1e-12)
    np.testing.assert_allclose(y[:, 5], y[:, 0])
    np.testing.assert_array_equal(near, np.rint(np.linspace(0, 20, 31)).astype(int))
    y, near = resample_frames(x, 20, 10)
    np.testing.assert_allclose(y[:, 0, 0], np.arange(0, 21, 2.0))
    same, near = resample_frames(x, 20, 20)
    assert same is not None and np.array_equal(same, x) and np.array_equal(near, t.astype(int))


@pytest.mark.filterwarnings(BVH_WARNING)
def test_export_at_another_frame_rate_lasts_as_long(board, anim, tmp_path):
    """fps=30: 1.5x the frames at 1/30 s each in the BVH and both GIFs (same duration)."""
    out = export_storyboard(board, anim, tmp_path, formats=("bvh", "sketch_gif"), fps=30)
    n = int(round((len(anim.joints) - 1) * 1.5)) + 1
    info = check_bvh(out["bvh"], n_frames=n, fps=30)
    assert info["n_frames"] == n and info["fps"] == pytest.approx(30)
    np.testing.assert_allclose(info["joints"][0, 0], anim.joints[0, 0], atol=1e-6)
    np.testing.assert_allclose(info["joints"][-1, 0], anim.joints[-1, 0], atol=1e-6)
    from PIL import Image, ImageSequence

    with Image.open(out["sketch_gif"]) as gif:      # repeated frames may be merged
        seconds = sum(f.info["duration"] for f in ImageSequence.Iterator(gif)) / 1000
    assert seconds == pytest.approx(n / 30, abs=0.05)


# ----------------------------------------------------------------------------- BVH


@pytest.mark.filterwarnings(BVH_WARNING)
def test_bvh_round_trip(board, anim, tmp_path):
    path = export_storyboard(board, anim, tmp_path, formats=("bvh",))["bvh"]
    info = check_bvh(path, n_frames=len(anim.joints))
    # hierarchy order: depth-first, as BVH nests joints; parents map onto PARENTS
    assert info["names"][:5] == ["pelvis", "left_hip", "left_knee", "left_ankle", "left_foot"]
    assert sorted(info["names"]) == sorted(JOINT_NAMES)
    for k, name in enumerate(info["names"]):
        p = info["parents"][k]
        assert (p < 0 and name == "pelvis") or \
            info["names"][p] == JOINT_NAMES[PARENTS[JOINT_NAMES.index(name)]]
    assert info["frame_time"] == pytest.approx(0.05) and info["fps"] == pytest.approx(20)
    assert len(info["end_sites"]) == 5
    # the file is the exporter's rigid skeleton to float precision ...
    m = joints_to_bvh_motion(anim.joints, tol=np.inf)
    fk = m.joint_positions()[:, [m.joint_index(n) for n in JOINT_NAMES]]
    np.testing.assert_allclose(info["joints"], fk, atol=1e-6)
    # ... which is the generated animation within a few mm (its bones stretch a little)
    err = np.linalg.norm(info["joints"] - anim.joints, axis=-1)
    np.testing.assert_allclose(err[:, 0], 0.0, atol=1e-6)                 # the root exactly
    assert np.median(err) < 0.008 and err.mean() < 0.02 and err.max() < 0.12


def test_bvh_round_trip_of_a_rigid_animation_is_exact(board, anim, tmp_path):
    m = joints_to_bvh_motion(anim.joints, tol=np.inf)
    rigid = m.joint_positions()[:, [m.joint_index(n) for n in JOINT_NAMES]]
    with warnings.catch_warnings():
        warnings.simplefilter("error")                     # a rigid clip fits: no warning
        path = export_storyboard(board, dataclasses.replace(anim, joints=rigid), tmp_path,
                                 formats=("bvh",))["bvh"]
    assert np.abs(check_bvh(path)["joints"] - rigid).max() < 1e-3            # < 1 mm


def test_check_bvh_rejects_other_files(anim, tmp_path):
    x = anim.joints[:12]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        path = joints_to_bvh(x, tmp_path / "c.bvh")
    with pytest.raises(ValueError, match="12 frames, expected 11"):
        check_bvh(path, n_frames=11)
    with pytest.raises(ValueError, match=r"Frame Time 0.05 s is not 1/30"):
        check_bvh(path, fps=30)
    text = path.read_text()
    renamed = tmp_path / "renamed.bvh"
    renamed.write_text(text.replace("JOINT left_elbow", "JOINT left_forearm"))
    with pytest.raises(ValueError, match=r"missing \['left_elbow'\], unexpected "
                                         r"\['left_forearm'\]"):
        check_bvh(renamed)
    no_end = tmp_path / "no_end.bvh"             # head's End Site block removed
    lines = text.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.strip() == "JOINT head")
    e = next(i for i in range(k, len(lines)) if lines[i].strip() == "End Site")
    no_end.write_text("\n".join(lines[:e] + lines[e + 4:]) + "\n")
    with pytest.raises(ValueError, match="end sites"):
        check_bvh(no_end)
    m = read_bvh(path)                           # the head hung under spine3, not the neck
    parents = m.parents.copy()
    parents[m.names.index("head")] = m.names.index("spine3")
    moved = dataclasses.replace(m, parents=parents)
    with pytest.raises(ValueError, match="joint 'head' has parent 'spine3', not 'neck'"):
        check_bvh(write_bvh(tmp_path / "moved.bvh", moved))
    two = BVHMotion(names=["hips", "chest"], parents=[-1, 0], offsets=np.zeros((2, 3)),
                    channels=[["Xposition", "Yposition", "Zposition", "Zrotation",
                               "Xrotation", "Yrotation"], ["Zrotation", "Xrotation",
                                                           "Yrotation"]],
                    frame_time=0.05, motion=np.zeros((3, 9)))
    with pytest.raises(ValueError, match="22-joint HumanML3D skeleton"):
        check_bvh(write_bvh(tmp_path / "two.bvh", two))
