"""Bad input and faults at physlab's edges: video/GIF writers, atomic writes, images, meshes,
sizes a user types, and the ``physlab`` command. Each case must raise a clear error (naming
the argument, file or limit) or behave correctly — never lose a good file or hang."""
import os
import stat
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from physlab import render
from physlab._io import STALE_TEMP_SECONDS, atomic_write, remove_stale_temps

FRAMES = (np.random.default_rng(0).random((6, 32, 48, 3)) * 255).astype(np.uint8)


# ----------------------------------------------------------------------------- writers
def _good_mp4(tmp_path):
    path = render.frames_to_mp4(FRAMES, tmp_path / "a.mp4", fps=12)
    return path, path.read_bytes()


def _fake_ffmpeg(tmp_path, body):
    exe = tmp_path / "ffmpeg"
    exe.write_text("#!/bin/sh\n" + textwrap.dedent(body))
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return str(exe)


def _temps(tmp_path):
    return sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("."))


@pytest.mark.parametrize("body, cause", [
    ("head -c 2000 > /dev/null\nexit 1\n",                                       # dies early
     "ffmpeg failed while writing|ffmpeg wrote an unreadable MP4"),
    ('cat > /dev/null\nfor a; do last="$a"; done\nprintf junk > "$last"\n',     # lies: rc 0
     "ffmpeg wrote an unreadable MP4|ffmpeg wrote 0 of 6 frames"),
])
def test_a_failing_ffmpeg_keeps_the_previous_mp4(tmp_path, monkeypatch, body, cause):
    path, good = _good_mp4(tmp_path)
    real = __import__("imageio_ffmpeg").get_ffmpeg_exe()
    fake = _fake_ffmpeg(tmp_path / "..", body)
    # the fake writes; the real one reads back (count_frames_and_secs)
    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", fake)
    import imageio_ffmpeg
    monkeypatch.setattr(imageio_ffmpeg, "count_frames_and_secs",
                        lambda p: _count_with(real, p))
    with pytest.raises(RuntimeError, match=rf"could not write .*a\.mp4: ({cause}).*previous file"):
        render.frames_to_mp4(FRAMES[::-1], path, fps=12)
    assert path.read_bytes() == good and _temps(tmp_path) == []


def _count_with(exe, path):
    os.environ["IMAGEIO_FFMPEG_EXE"] = exe
    try:
        import imageio_ffmpeg._io as io
        return io.count_frames_and_secs(path)
    finally:
        os.environ.pop("IMAGEIO_FFMPEG_EXE", None)


def test_a_file_size_limit_keeps_the_previous_mp4(tmp_path):
    """Disk full, simulated by RLIMIT_FSIZE in a child process (ffmpeg inherits it)."""
    _, good = _good_mp4(tmp_path)
    code = textwrap.dedent(f"""
        import resource, signal, numpy as np
        from physlab import render
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))
        noise = (np.random.default_rng(1).random((40, 96, 128, 3)) * 255).astype(np.uint8)
        try:
            render.frames_to_mp4(noise, {str(tmp_path / 'a.mp4')!r}, fps=12)
        except RuntimeError as e:
            print("ERR", e)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert "ERR could not write" in out.stdout and "previous file" in out.stdout, out
    assert (tmp_path / "a.mp4").read_bytes() == good and _temps(tmp_path) == []


def test_temp_files_of_killed_writers_are_cleaned_on_the_next_write(tmp_path):
    target = tmp_path / "clip.gif"
    old = tmp_path / ".clip.0123456789abcdef.gif"          # a killed writer's leftover
    fresh = tmp_path / ".clip.fedcba9876543210.gif"        # a writer still at work
    other = tmp_path / ".clip.0123456789abcdef.mp4"        # another target's
    for p in (old, fresh, other):
        p.write_bytes(b"partial")
    past = time.time() - STALE_TEMP_SECONDS - 5
    os.utime(old, (past, past))
    os.utime(other, (past, past))
    render.frames_to_gif(FRAMES, target, fps=10)
    assert target.is_file() and not old.exists() and fresh.exists() and other.exists()
    assert remove_stale_temps(tmp_path / "clip.mp4", ".mp4") == 1 and not other.exists()


def test_atomic_write_gives_the_usual_mode_without_touching_the_umask(tmp_path):
    before = os.umask(0o022)
    try:
        p = atomic_write(tmp_path / "x.txt", lambda t: open(t, "w").write("hi"))
        assert stat.S_IMODE(p.stat().st_mode) == 0o644
        assert os.umask(0o022) == 0o022                   # unchanged by the write
    finally:
        os.umask(before)


def test_a_failed_write_leaves_the_old_file_and_no_temp(tmp_path):
    p = tmp_path / "keep.txt"
    p.write_text("good")

    def boom(tmp):
        open(tmp, "w").write("half")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_write(p, boom)
    assert p.read_text() == "good" and _temps(tmp_path) == []


NAN = np.full((2, 8, 8, 3), np.nan)


@pytest.mark.parametrize("call, match", [
    (lambda d: render.frames_to_gif(NAN, d / "a.gif"), r"NaN/inf values \(first in frame 0\)"),
    (lambda d: render.frames_to_mp4(NAN, d / "a.mp4"), r"NaN/inf"),
    (lambda d: render.frames_to_gif(np.zeros((0, 8, 8, 3)), d / "a.gif"), r"T, H, W >= 1"),
    (lambda d: render.frames_to_gif(np.zeros((2, 8, 8, 5)), d / "a.gif"), r"\(T, H, W, 3\|4\)"),
    (lambda d: render.frames_to_gif(np.zeros((8, 8)), d / "a.gif"), r"\(T, H, W, 3\|4\)"),
    (lambda d: render.frames_to_gif(np.zeros((2, 8, 8, 3), np.int64), d / "a.gif"),
     r"dtype int64"),
    (lambda d: render.frames_to_gif(FRAMES, d / "a.gif", fps=0), r"fps must be a number"),
    (lambda d: render.frames_to_gif(FRAMES, d / "a.gif", fps=float("nan")), r"fps must be"),
    (lambda d: render.frames_to_gif(FRAMES, d / "a.gif", fps=1e9), r"fps must be .*1000"),
    (lambda d: render.frames_to_mp4(FRAMES, d / "a.mp4", fps=-1), r"fps must be"),
    (lambda d: render.frames_to_mp4(FRAMES, d / "a.mp4", crf=99), r"crf must be .*0\.\.51"),
    (lambda d: render.frames_to_mp4(FRAMES, d / "a.mp4", fps=True), r"fps must be"),
])
def test_writers_refuse_bad_frames_and_settings(tmp_path, call, match):
    with pytest.raises(ValueError, match=match):
        call(tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_16_bit_and_bool_frames_are_converted_by_range(tmp_path):
    f16 = (FRAMES.astype(np.uint16) * 257)
    assert np.array_equal(render._frames_uint8(f16), FRAMES)
    b = np.zeros((1, 4, 4, 3), bool)
    b[0, 0, 0] = True
    assert render._frames_uint8(b)[0, 0, 0, 0] == 255 and render._frames_uint8(b).max() == 255


# ----------------------------------------------------------------------------- images
from physlab import mesh as M  # noqa: E402
from physlab.image import as_float, over_white, read_image, to_uint8  # noqa: E402


def _disk_image(dtype=np.uint8, size=64, r=20):
    yy, xx = np.mgrid[:size, :size]
    ink = np.hypot(xx - size / 2, yy - size / 2) < r
    img = np.where(ink[..., None], 0.1, 1.0) * np.ones(3)
    if dtype == np.uint16:
        return (img * 65535).astype(np.uint16), ink
    return (img * 255).astype(np.uint8), ink


def test_a_16_bit_image_is_read_by_range_not_wrapped(tmp_path):
    import imageio.v3 as iio

    img16, ink = _disk_image(np.uint16)
    img16 = img16[..., 0]                          # a 16-bit grey PNG (Pillow writes I;16)
    path = tmp_path / "d16.png"
    iio.imwrite(path, img16)
    back = read_image(path)
    assert back.dtype == np.uint16
    m = M.foreground_mask(back, dilate_radius=0)
    iou = (m & ink).sum() / (m | ink).sum()
    assert iou > 0.95, iou                    # wrapped by astype(uint8) it was 0.25
    img8, _ = _disk_image(np.uint8)
    assert np.array_equal(M.foreground_mask(back), M.foreground_mask(img8[..., 0]))
    assert np.array_equal(to_uint8(img16), (img16 // 257).astype(np.uint8))


BLACK = np.zeros((40, 40, 3), np.uint8)
WHITE = np.full((40, 40, 3), 255, np.uint8)


@pytest.mark.parametrize("call, exc, match", [
    (lambda: M.meshes_from_image(BLACK), ValueError, "no foreground found"),
    (lambda: M.meshes_from_image(WHITE), ValueError, "no foreground found"),
    (lambda: M.meshes_from_image(np.full((40, 40, 3), 0.5)), ValueError, "no foreground found"),
    (lambda: M.foreground_mask(np.zeros((0, 0, 3), np.uint8)), ValueError, "empty or too small"),
    (lambda: M.foreground_mask(np.zeros((5, 5, 2), np.uint8)), ValueError, r"shape \(H, W\)"),
    (lambda: M.foreground_mask(np.zeros((5, 5), np.int64)), ValueError, "dtype int64"),
    (lambda: M.foreground_mask(np.full((5, 5), np.nan)), ValueError, "NaN or inf"),
    (lambda: M.foreground_mask(np.full((5, 5), 3.0)), ValueError, r"\[0, 1\]"),
    (lambda: M.foreground_mask(np.zeros((5, 5), bool)), ValueError, "mask_from_array"),
    (lambda: M.mesh_from_mask(np.zeros((9, 9), bool)), ValueError, "mask is empty"),
    (lambda: M.mesh_from_mask(np.ones((9, 9), bool), epsilon=-1), ValueError, "epsilon"),
    (lambda: M.mesh_from_mask(np.ones((9, 9), bool), epsilon=float("nan")), ValueError,
     "epsilon"),
    (lambda: as_float(np.zeros((4, 4, 3)), channels=5), ValueError, "channels must be"),
    (lambda: as_float(np.zeros((4, 4, 3), np.complex64), "key0"), ValueError, "key0 must be"),
    (lambda: over_white(np.zeros((4, 4, 7))), ValueError, r"shape \(H, W\)"),
    (lambda: read_image("/nonexistent/x.png"), FileNotFoundError, "does not exist"),
])
def test_image_and_mask_inputs(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


def test_read_image_names_a_corrupt_file(tmp_path):
    p = tmp_path / "broken.png"
    p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)
    with pytest.raises(ValueError, match=r"broken\.png is not a readable image"):
        read_image(p)


# ----------------------------------------------------------------------------- meshes
def _mesh_area(m):
    return float(M.triangle_areas(m.X, m.tris).sum())


@pytest.mark.parametrize("name, mask", [
    ("U 3x28", lambda: _u_shape()),
    ("1-px stroke of 103 px", lambda: _stroke()),
])
def test_meshes_keep_the_area_of_their_masks(name, mask):
    m = mask()
    area = _mesh_area(M.mesh_from_mask(m))
    assert abs(area - m.sum()) <= 0.1 * m.sum(), (name, area, m.sum())


def _u_shape():
    m = np.zeros((40, 40), bool)
    m[5:33, 5:8] = m[5:33, 12:15] = m[30:33, 5:15] = True
    return m


def _stroke():
    m = np.zeros((20, 120), bool)
    m[10, 5:108] = True
    return m


@pytest.mark.parametrize("tris, match", [
    ([[0, 1, 2], [0, 1, 2]], "duplicate triangle"),
    ([[0, 1, 2], [2, 0, 1]], "duplicate triangle"),          # same triangle, rotated
    ([[0, 1, 2], [1, 0, 2]], "duplicate triangle"),          # same triangle, flipped
    ([[0, 1, 3]], "does not exist"),
    ([[0, 1]], r"shape \(T, 3\)"),
    ([[0, 1, 1]], "degenerate"),
])
def test_trimesh_rejects_bad_triangles(tris, match):
    X = np.array([[0.0, 0], [1, 0], [0, 1]])
    with pytest.raises(ValueError, match=match):
        M.TriMesh(X, np.array(tris))


def test_trimesh_refuses_coordinates_whose_areas_overflow():
    X = np.array([[0.0, 0.0], [1e154, 0], [0, 1e154]])
    with pytest.raises(ValueError, match="coordinates up to 1e\\+154"):
        M.TriMesh(X, np.array([[0, 1, 2]]))


def test_triangle_count_is_bounded_before_calling_triangle():
    square = np.array([[0.0, 0], [1000, 0], [1000, 1000], [0, 1000]])
    with pytest.raises(ValueError, match=r"limit of 2,000,000; choose max_area >= 0\.5"):
        M.triangulate_polygon(square, max_area=1e-3)
    with pytest.raises(ValueError, match="max_area must be a finite number"):
        M.triangulate_polygon(square, max_area=float("inf"))


# ----------------------------------------------------------------------------- sizes a user types
def test_inbetween_refuses_absurd_frame_counts_at_once():
    from physlab.inbetween import Skeleton, inbetween

    key = np.zeros((64, 64, 4))
    sk = Skeleton(["a", "b"], [-1, 0], [[20.0, 20.0], [40.0, 40.0]])
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"n_frames = 10000000 is too many .* limit is 1000"):
        inbetween(key, key, sk, sk, 10**7)
    for bad in (1, 2.5, True, float("nan"), "9"):
        with pytest.raises(ValueError, match="n_frames must be an integer"):
            inbetween(key, key, sk, sk, bad)
    assert time.perf_counter() - t0 < 5


# ----------------------------------------------------------------------------- the command
@pytest.mark.parametrize("args, match", [
    (["animate", "--out", "a.avi"], r"--out a\.avi: cannot write \.avi; use one of \.gif, \.mp4"),
    (["animate", "--out", "noext"], r"cannot write a file without extension"),
    (["animate", "--control-out", "c.png"], r"--control-out c\.png: cannot write \.png"),
    (["animate", "--duration", "-1"], r"--duration must be in \(0, 60\] seconds"),
    (["animate", "--duration", "1e9"], r"--duration must be in"),
    (["animate", "--fps", "0"], r"--fps must be in 1\.\.120"),
    (["animate", "--fps", "abc"], r"argument --fps: invalid int value: 'abc'"),
    (["animate", "--drawing", "/nonexistent/x.png"], r"drawing file /nonexistent/x\.png does not"),
    (["animate", "--drawing", "dragon"], r"drawing must be one of \['ball'"),
    (["reproduce", "--lessons", "99"], r"no lesson matches \['99'\]"),
    (["execute", "/nonexistent.ipynb"], r"no notebook at /nonexistent\.ipynb"),
    (["bogus"], r"argument cmd: invalid choice: 'bogus'"),
    ([], r"the following arguments are required: cmd"),
])
def test_physlab_command_prints_one_line_and_exits_2(args, match, capsys, tmp_path,
                                                     monkeypatch):
    from physlab import cli

    monkeypatch.chdir(tmp_path)
    try:
        status = cli.main(args)
    except SystemExit as e:                       # argparse's own errors
        status = e.code
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, err
    assert err[0].startswith("physlab: error: ")
    import re
    assert re.search(match, err[0]), err[0]
    assert list(tmp_path.iterdir()) == []


def test_debug_shows_the_traceback():
    from physlab import cli

    with pytest.raises(ValueError, match="cannot write .avi"):
        cli.main(["--debug", "animate", "--out", "a.avi"])
    with pytest.raises(ValueError, match="cannot write .avi"):
        cli.main(["animate", "--debug", "--out", "a.avi"])


# ----------------------------------------------------------------------------- mask -> mesh fuzzer
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_SHAPES = st.lists(st.tuples(st.sampled_from(["disk", "bar", "line", "ring", "hole"]),
                             st.integers(2, 38), st.integers(2, 38), st.integers(1, 14)),
                   min_size=1, max_size=4)


def _paint(shapes, size=40):
    yy, xx = np.mgrid[:size, :size]
    m = np.zeros((size, size), bool)
    for kind, cx, cy, r in shapes:
        d = np.hypot(xx - cx, yy - cy)
        if kind == "disk":
            m |= d <= r
        elif kind == "bar":
            m |= (abs(xx - cx) <= r) & (abs(yy - cy) <= 1)
        elif kind == "line":
            m |= (xx == cx) & (abs(yy - cy) <= r)
        elif kind == "ring":
            m |= (d <= r) & (d >= r - 1.5)
        else:
            m &= ~(d <= r / 2)
    return m


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(_SHAPES)
def test_mask_to_mesh_fuzz_keeps_the_area_or_says_why(shapes):
    """Random blobs, thin strokes, rings and holes: the mesh of the largest component has its
    area (holes below MIN_HOLE_AREA filled, larger ones left out) within 10 % (or 12 px² for
    tiny ones), or a clear ValueError."""
    m = _paint(shapes)
    try:
        mesh = M.mesh_from_mask(m)
    except ValueError as e:
        assert "empty" in str(e) or "area" in str(e) or "polygon" in str(e), e
        return
    comp = M.fill_small_holes(M._largest_component(M.mask_from_array(m)))
    area, target = _mesh_area(mesh), float(comp.sum())
    assert abs(area - target) <= max(0.1 * target, 12.0), (area, target)
    assert len(np.unique(np.sort(mesh.tris, axis=1), axis=0)) == len(mesh.tris)
