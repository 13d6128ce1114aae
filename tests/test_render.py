"""physlab.render: textured-mesh warp, compositing, control images, video out."""
import numpy as np
import pytest

from physlab import render


# ---------------------------------------------------------------------------- helpers
def grid_mesh(H, W, ny, nx):
    """Grid mesh covering an H×W image exactly (corners at -0.5 and W-0.5 / H-0.5)."""
    xs = np.linspace(-0.5, W - 0.5, nx + 1)
    ys = np.linspace(-0.5, H - 0.5, ny + 1)
    X = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    i = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None]).ravel()
    tris = np.concatenate([np.stack([i, i + 1, i + nx + 2], 1),
                           np.stack([i, i + nx + 2, i + nx + 1], 1)])
    return X, tris


def checker(H, W, square=8, circle=True):
    """RGB float texture: checkerboard with a red disk and dark strokes (asymmetric)."""
    yy, xx = np.mgrid[:H, :W]
    c = ((xx // square + yy // square) % 2).astype(np.float32)
    img = np.stack([0.2 + 0.6 * c, 0.3 + 0.5 * c, 0.9 - 0.7 * c], -1)
    if circle:
        disk = (xx - 0.6 * W) ** 2 + (yy - 0.4 * H) ** 2 < (0.2 * min(H, W)) ** 2
        img[disk] = (0.9, 0.1, 0.1)
        img[int(0.75 * H):int(0.75 * H) + 3, int(0.1 * W):int(0.5 * W)] = 0.05   # stroke
        img[int(0.1 * H):int(0.6 * H), int(0.2 * W):int(0.2 * W) + 2] = 0.05
    return img.astype(np.float32)


def psnr(a, b):
    mse = np.mean((np.asarray(a, float) - np.asarray(b, float)) ** 2)
    return np.inf if mse == 0 else 10 * np.log10(1.0 / mse)


def signed_areas(x, tris):
    a, b, c = x[tris[:, 0]], x[tris[:, 1]], x[tris[:, 2]]
    u, v = b - a, c - a
    return 0.5 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


# ------------------------------------------------------------------------ warp_texture
@pytest.mark.parametrize("s", [1, 2, 3])
def test_identity_warp_reproduces_texture(s):
    tex = checker(48, 64)
    X, tris = grid_mesh(48, 64, 5, 7)
    out = render.warp_texture(tex, X, X, tris, (48, 64), supersample=s)
    assert out.shape == (48, 64, 4) and out.dtype == np.float32
    assert psnr(out[2:-2, 2:-2, :3], tex[2:-2, 2:-2]) > 35
    # two triangles covering the whole texture: exact everywhere, fully opaque
    X2 = np.array([[-0.5, -0.5], [63.5, -0.5], [63.5, 47.5], [-0.5, 47.5]])
    t2 = np.array([[0, 1, 2], [0, 2, 3]])
    out2 = render.warp_texture(tex, X2, X2, t2, (48, 64), supersample=s)
    np.testing.assert_allclose(out2[..., :3], tex, atol=1e-5)
    np.testing.assert_allclose(out2[..., 3], 1.0, atol=1e-6)


def test_integer_translation_shifts_exactly():
    tex = checker(40, 40)
    X, tris = grid_mesh(40, 40, 6, 6)
    dx, dy = 7, -4
    out = render.warp_texture(tex, X, X + [dx, dy], tris, (40, 40))
    # output pixel (row i, col j) shows texture pixel (i - dy, j - dx)
    np.testing.assert_allclose(out[1:35, 8:39, :3], tex[5:39, 1:32], atol=1e-5)
    np.testing.assert_allclose(out[1:35, 8:39, 3], 1.0, atol=1e-6)
    assert np.all(out[:, :7, 3] == 0) and np.all(out[-4:, :, 3] == 0)   # uncovered


def test_rotation_by_90_degrees_matches_rot90():
    N = 32
    tex = checker(N, N)
    X, tris = grid_mesh(N, N, 4, 4)
    # np.rot90: out[i, j] = tex[j, N-1-i]  ->  texture (u, v) lands at (x, y) = (v, N-1-u)
    x = np.stack([X[:, 1], N - 1 - X[:, 0]], 1)
    out = render.warp_texture(tex, X, x, tris, (N, N))
    ref = np.rot90(tex)
    np.testing.assert_allclose(out[1:-1, 1:-1, :3], ref[1:-1, 1:-1], atol=1e-5)
    # a counter-clockwise rotation of the array is clockwise on screen with y down: the
    # texture's top-left corner ends at the bottom-left
    assert np.linalg.norm(x[0] - [-0.5, N - 0.5]) < 1e-12


def test_mirrored_inverted_mesh_renders_fliplr():
    tex = checker(30, 36)
    X, tris = grid_mesh(30, 36, 3, 4)
    x = X.copy()
    x[:, 0] = 36 - 1 - X[:, 0]                      # every triangle inverted
    assert np.all(np.sign(signed_areas(x, tris)) == -np.sign(signed_areas(X, tris)))
    out = render.warp_texture(tex, X, x, tris, (30, 36))
    np.testing.assert_allclose(out[1:-1, 1:-1, :3], np.fliplr(tex)[1:-1, 1:-1], atol=1e-5)
    np.testing.assert_allclose(out[1:-1, 1:-1, 3], 1.0, atol=1e-6)


def _affine_case():
    from skimage.transform import AffineTransform

    tex = checker(64, 64, square=8, circle=False)
    tf = AffineTransform(scale=(1.15, 0.9), rotation=0.35, shear=0.2, translation=(12, -4))
    X, tris = grid_mesh(64, 64, 8, 8)
    return tex, tf, X, tris


def test_affine_warp_agrees_with_skimage_warp():
    """Independent reference: skimage.transform.warp (bilinear) with the same transform."""
    from skimage.transform import warp

    tex, tf, X, tris = _affine_case()
    x = tf(X)
    ref = warp(tex, tf.inverse, output_shape=(80, 90), order=1, mode="edge")
    inside = render.warp_texture(np.ones((64, 64)), X, x, tris, (80, 90), supersample=1)[..., 3]
    from scipy.ndimage import binary_erosion

    interior = binary_erosion(inside > 0.999, iterations=2)
    assert interior.sum() > 2000
    out1 = render.warp_texture(tex, X, x, tris, (80, 90), supersample=1)
    assert psnr(out1[interior, :3], ref[interior]) > 40      # same sampling: ~OpenCV rounding
    out2 = render.warp_texture(tex, X, x, tris, (80, 90), supersample=2)
    assert psnr(out2[interior, :3], ref[interior]) > 30      # + antialiasing differences
    # a wrong transform (e.g. y up instead of y down) fails clearly
    bad = render.warp_texture(tex, X, tf(X * [1, -1] + [0, 63]), tris, (80, 90), supersample=1)
    assert psnr(bad[interior, :3], ref[interior]) < 15


def test_coverage_equals_deformed_area_and_edges_are_antialiased():
    tex = np.ones((50, 50, 3))
    X, tris = grid_mesh(50, 50, 10, 10)
    c = np.array([60.0, 55.0])
    th = 0.3 + 0.01 * np.linalg.norm(X - 25, axis=1)          # smooth twist, no fold-over
    R = np.stack([np.cos(th), -np.sin(th), np.sin(th), np.cos(th)], 1).reshape(-1, 2, 2)
    x = c + 1.3 * np.einsum("nij,nj->ni", R, X - 25)
    A = signed_areas(x, tris)
    assert np.all(A > 0)
    for s, tol in [(1, 0.02), (2, 0.01), (4, 0.005)]:
        alpha = render.warp_texture(tex, X, x, tris, (120, 120), supersample=s)[..., 3]
        assert abs(alpha.sum() - A.sum()) < tol * A.sum(), (s, alpha.sum(), A.sum())
        # inverted copy covers the same area
        alpha_m = render.warp_texture(tex, X, x * [-1, 1] + [119, 0], tris, (120, 120), s)[..., 3]
        np.testing.assert_allclose(alpha_m.sum(), alpha.sum(), rtol=1e-9)
    frac = (alpha > 0.02) & (alpha < 0.98)
    assert frac.sum() > 100                                   # a fractional-alpha silhouette
    assert alpha.max() <= 1.0 and np.all(alpha[:, :2] == 0)   # no double coverage inside


def test_warp_outside_and_bad_inputs():
    tex = checker(8, 8)
    X, tris = grid_mesh(8, 8, 1, 1)
    off = render.warp_texture(tex, X, X + 1000, tris, (10, 10))
    assert np.all(off == 0)
    with pytest.raises(ValueError, match="NaN"):
        render.warp_texture(tex, X, X * np.nan, tris, (10, 10))
    with pytest.raises(ValueError, match="outside"):
        render.warp_texture(tex, X, X, tris + 10, (10, 10))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        render.warp_texture(tex * 255, X, X, tris, (10, 10))
    with pytest.raises(ValueError, match="supersample"):
        render.warp_texture(tex, X, X, tris, (10, 10), supersample=0)


def test_warp_reference_numbers():
    """Fixed reference, by hand: a 2×2 texture stretched ×2 to 4×4 at supersample 2.

    Fine texture (×2 replication) along an axis: [a, a, b, b]; output fine pixel p samples it
    at q = p/2 - 1/4, i.e. a, a, a, (3a+b)/4, (a+3b)/4, b, b, b; box pairs give the per-axis
    weights (a, b): (1, 0), (7/8, 1/8), (1/8, 7/8), (0, 1). Bilinear and box are separable.
    """
    T = np.array([[0.0, 1.0], [0.5, 0.25]])
    tex = T[..., None].repeat(3, 2)
    X = np.array([[-0.5, -0.5], [1.5, -0.5], [1.5, 1.5], [-0.5, 1.5]])
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    out = render.warp_texture(tex, X, 2 * X + 0.5, tris, (4, 4), supersample=2)
    Wt = np.array([[1, 0], [7 / 8, 1 / 8], [1 / 8, 7 / 8], [0, 1]])
    np.testing.assert_allclose(out[..., 0], Wt @ T @ Wt.T, atol=1e-6)
    assert out[1, 1, 0] == pytest.approx(0.16796875, abs=1e-6)   # = 43/256
    np.testing.assert_array_equal(out[..., 0], out[..., 2])


# --------------------------------------------------------------------------- composite
def test_composite_alpha_over_by_hand():
    red = np.zeros((2, 3, 4)); red[..., 0] = 1; red[..., 3] = 0.5
    blue = np.zeros((2, 3, 4)); blue[..., 2] = 1; blue[..., 3] = 0.25
    out = render.composite([red, blue])                     # white background
    np.testing.assert_allclose(out, np.broadcast_to([0.75, 0.375, 0.625], (2, 3, 3)), atol=1e-6)
    out8 = render.composite([blue, red], background=(0, 0, 0), dtype=np.uint8)
    # blue over black = (0, 0, .25); red (α=.5) over it = (.5, 0, .125)
    np.testing.assert_array_equal(out8[0, 0], [128, 0, 32])
    np.testing.assert_allclose(render.composite([], size=(2, 2), background=(0.2, 0.4, 0.6)),
                               np.broadcast_to([0.2, 0.4, 0.6], (2, 2, 3)), atol=1e-7)
    bg = np.zeros((2, 3, 4)); bg[..., 1] = 1; bg[..., 3] = 0.5   # RGBA background over white
    np.testing.assert_allclose(render.composite([], background=bg)[0, 0], [0.5, 1, 0.5], atol=1e-7)
    with pytest.raises(ValueError, match="disagree"):
        render.composite([red], size=(5, 5))
    with pytest.raises(ValueError, match="size"):
        render.composite([])


def test_render_bodies_respects_depth():
    size = (20, 20)
    red = np.zeros((4, 4, 3)); red[..., 0] = 1
    green = np.zeros((4, 4, 3)); green[..., 1] = 1
    X = np.array([[-0.5, -0.5], [3.5, -0.5], [3.5, 3.5], [-0.5, 3.5]])
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    xa = X * 3 + [2, 2]                                      # [0.5, 12.5]^2
    xb = X * 3 + [7, 7]                                      # overlaps on [5.5, 12.5]^2
    args = ([red, green], [X, X], [xa, xb], [tris, tris], size)
    f = render.render_bodies(*args)                          # list order: green on top
    assert f.shape == (20, 20, 3) and f.dtype == np.uint8
    np.testing.assert_array_equal(f[9, 9], [0, 255, 0])
    np.testing.assert_array_equal(f[3, 3], [255, 0, 0])
    np.testing.assert_array_equal(f[0, 19], [255, 255, 255])  # background
    f = render.render_bodies(*args, depth=[0.0, 1.0])        # green further back
    np.testing.assert_array_equal(f[9, 9], [255, 0, 0])
    np.testing.assert_array_equal(f[15, 15], [0, 255, 0])


def test_warp_renderer_protocol_and_control():
    tex = checker(32, 32)
    X, tris = grid_mesh(32, 32, 4, 4)
    r = render.WarpRenderer([tex, tex], [X, X], [tris, tris], (40, 48), control=True,
                            depth=[[0, 1], [1, 0]])
    assert isinstance(r, render.Renderer)
    pos = [X + 2, X + [14, 6]]
    f0 = r.render(0, pos)
    assert f0.shape == (40, 48, 3) and f0.dtype == np.uint8
    expect = render.render_bodies([tex, tex], [X, X], pos, [tris, tris], (40, 48), depth=[0, 1])
    np.testing.assert_array_equal(f0, expect)
    assert not np.array_equal(r.render(1, pos), f0)         # per-frame depth swaps the order
    c = r.render_control(0, pos)
    assert c.shape == (40, 48) and c.dtype == np.uint8 and set(np.unique(c)) == {0, 255}
    frames, controls = r.render_sequence([pos, pos])
    assert frames.shape == (2, 40, 48, 3) and controls.shape == (2, 40, 48)
    with pytest.raises(ValueError, match="one"):
        r.render(0, pos[:1])


# ---------------------------------------------------------------------------- edge_map
def _distance_error(edges, centre, r):
    yy, xx = np.nonzero(edges == 0)
    d = np.hypot(xx - centre[0], yy - centre[1])
    return np.mean(np.abs(d - r)), len(d)


@pytest.mark.parametrize("method,tol", [("canny", 1.5), ("dog", 2.0)])
def test_edge_map_of_filled_circle_is_a_ring(method, tol):
    from skimage.draw import disk

    H, W, r, c = 96, 110, 30.0, (52.0, 45.0)               # centre (x, y)
    img = np.ones((H, W, 3))
    rr, cc = disk((c[1], c[0]), r, shape=(H, W))
    img[rr, cc] = (0.1, 0.3, 0.6)
    e = render.edge_map(img, sigma=1.0, method=method)
    assert e.shape == (H, W) and e.dtype == np.uint8 and set(np.unique(e)) == {0, 255}
    err, n = _distance_error(e, c, r)
    assert err < tol and n > 2 * np.pi * r * 0.8            # near r, and all round
    assert e[int(c[1]), int(c[0])] == 255 and e[2, 2] == 255  # no ink inside or outside


def test_edge_map_sees_alpha_silhouettes_and_dilates():
    img = np.ones((40, 40, 4))                              # white on white: only alpha shows
    img[..., 3] = 0
    img[10:30, 10:30, 3] = 1
    e = render.edge_map(img)
    assert (e == 0).sum() > 60
    thick = render.edge_map(img, dilate=1)
    assert (thick == 0).sum() > 2 * (e == 0).sum() and np.all(thick[e == 0] == 0)
    with pytest.raises(ValueError, match="method"):
        render.edge_map(img, method="sobel")


def test_edge_map_rgb_channels_find_isoluminant_boundaries():
    img = np.zeros((40, 40, 3))
    img[..., 2] = 1.0                                       # blue, luma 0.0721
    img[:, 20:, :] = 0
    img[:, 20:, 0] = 0.0721 / 0.2125                        # red of the same luma
    assert render.edge_map(img).min() == 255                # invisible to luminance
    e = render.edge_map(img, channels="rgb")
    cols = np.nonzero(e[20] == 0)[0]
    assert len(cols) and np.all(np.abs(cols - 19.5) <= 1)


# ----------------------------------------------------------------------------- outputs
def _frames(T=5, H=24, W=30):
    f = np.zeros((T, H, W, 3), np.uint8)
    f[..., 0] = (np.arange(T) * 50)[:, None, None]
    f[:, 4:12, 5:20, 1] = 200
    return f


def test_frames_to_gif_roundtrip(tmp_path):
    import imageio.v3 as iio

    p = render.frames_to_gif(_frames(), tmp_path / "sub" / "a.gif", fps=10)
    back = iio.imread(p, index=None)
    assert back.shape[:3] == (5, 24, 30)
    assert [q.name for q in p.parent.iterdir()] == ["a.gif"]  # no temp file left


def test_gif_frame_times_add_up_to_the_duration(tmp_path):
    """GIF frame times are whole centiseconds: at 30 fps they alternate so that T frames
    last T / 30 s to 10 ms (a plain 30 ms would play 10 % fast); above 50 fps a clear error."""
    from PIL import Image, ImageSequence

    rng = np.random.default_rng(0)
    frames = rng.integers(0, 255, (31, 8, 8, 3), dtype=np.uint8)      # all different
    for fps in (30, 20, 7):
        p = render.frames_to_gif(frames, tmp_path / f"{fps}.gif", fps=fps)
        with Image.open(p) as gif:
            ms = [f.info["duration"] for f in ImageSequence.Iterator(gif)]
        assert len(ms) == 31 and all(m % 10 == 0 and m > 0 for m in ms), ms
        assert abs(sum(ms) - 31000 / fps) <= 10, (fps, sum(ms))
    with pytest.raises(ValueError, match="fps must be at most 50 for a GIF"):
        render.frames_to_gif(frames, tmp_path / "fast.gif", fps=60)


def test_frames_to_mp4_roundtrip(tmp_path):
    import imageio_ffmpeg

    p = render.frames_to_mp4(_frames(T=7), tmp_path / "a.mp4", fps=12)
    reader = imageio_ffmpeg.read_frames(str(p))
    meta = next(reader)
    frames = [np.frombuffer(b, np.uint8) for b in reader]
    assert meta["size"] == (30, 24) and len(frames) == 7
    f4 = frames[4].reshape(24, 30, 3)                       # red = 4 * 50
    assert abs(int(f4[20, 25, 0]) - 200) < 12 and abs(int(f4[8, 12, 1]) - 200) < 12
    assert [q.name for q in tmp_path.iterdir()] == ["a.mp4"]
    odd = render.frames_to_mp4(_frames(T=2, H=23, W=31), tmp_path / "odd.mp4", fps=12)
    assert next(imageio_ffmpeg.read_frames(str(odd)))["size"] == (32, 24)   # padded to even


def test_frames_to_html():
    pytest.importorskip("IPython")
    v = render.frames_to_html(_frames(), fps=10)
    assert "<video" in v.data and "base64," in v.data
    g = render.frames_to_html(_frames(), fps=10, fmt="gif")
    assert "<img" in g.data and "image/gif;base64," in g.data


def test_16_bit_frames_are_converted_by_range_like_image_to_uint8():
    """Every uint16 value v becomes round(v / 257) (never wrapped), as physlab.image.to_uint8
    converts it; fixed references at the rounding boundaries (v = 257 k ± 128.5)."""
    from physlab.image import to_uint8

    v = np.arange(65536, dtype=np.uint16).reshape(-1, 16, 16, 1).repeat(3, 3)  # (256, 16, 16, 3)
    u = render._frames_uint8(v)
    assert u.dtype == np.uint8 and u.shape == v.shape
    np.testing.assert_array_equal(u, np.round(v / 257).astype(np.uint8))
    np.testing.assert_array_equal(u, to_uint8(v))
    ref = np.array([0, 128, 129, 32767, 32768, 65406, 65407, 65535], np.uint16)
    got = render._frames_uint8(np.broadcast_to(ref[None, :, None, None], (1, 8, 1, 3)))
    assert got[0, :, 0, 0].tolist() == [0, 0, 1, 127, 128, 254, 255, 255]


def test_float_frames_round_in_their_own_precision_and_clip():
    """float32 frames: (x·255 + 0.5) in float32 (so the writers' output is unchanged at the
    k + 1/2 boundaries), overshoot clipped; uint8 frames are passed through, not copied."""
    k = np.arange(256)
    x = ((k + 0.5) / 255).astype(np.float32)
    x = np.concatenate([x, np.nextafter(x, np.float32(2)), np.nextafter(x, np.float32(-1)),
                        np.float32([-0.3, 1.2, 1.0 + 1e-6])])               # 771 = 257 × 3
    f = x.reshape(1, -1, 1, 3)
    u = render._frames_uint8(f)
    np.testing.assert_array_equal(u, (np.clip(f, 0, 1) * np.float32(255) + np.float32(0.5))
                                  .astype(np.uint8))
    assert u.ravel()[-3:].tolist() == [0, 255, 255]
    f8 = _frames()
    assert render._frames_uint8(f8) is f8


def test_16_bit_frames_write_the_same_gif_as_8_bit(tmp_path):
    import imageio.v3 as iio

    f8 = _frames()
    f16 = f8.astype(np.uint16) * 257 + np.uint16(100)       # +100 < 128.5: rounds back to f8
    a = iio.imread(render.frames_to_gif(f8, tmp_path / "a8.gif", fps=10), index=None)
    b = iio.imread(render.frames_to_gif(f16, tmp_path / "a16.gif", fps=10), index=None)
    np.testing.assert_array_equal(a, b)


def test_composite_over_a_16_bit_rgba_background_equals_8_bit():
    """An RGBA background is flattened over white by physlab.image.over_white whatever its
    bit depth: 16-bit (x·257) and 8-bit give the same canvas; a fixed reference pixel."""
    bg8 = np.zeros((4, 5, 4), np.uint8)
    bg8[..., 0] = 255
    bg8[..., 3] = np.array([0, 51, 102, 255, 255], np.uint8)   # alpha 0, 0.2, 0.4, 1, 1
    bg16 = bg8.astype(np.uint16) * 257
    c8 = render.composite([], background=bg8)
    c16 = render.composite([], background=bg16)
    np.testing.assert_allclose(c16, c8, atol=1e-6)
    np.testing.assert_allclose(c8[0, 1], [1.0, 0.8, 0.8], atol=1e-6)    # red at 20 % over white
    np.testing.assert_array_equal(render.composite([], background=bg16, dtype=np.uint8)[0],
                                  [[255, 255, 255], [255, 204, 204], [255, 153, 153],
                                   [255, 0, 0], [255, 0, 0]])


def test_rasterisation_is_watertight_under_jitter():
    """Jittered interior vertices, fixed boundary: every pixel centre of the square is covered
    exactly once (no cracks along shared edges, no double coverage)."""
    rng = np.random.default_rng(0)
    H, W = 37, 45
    X, tris = grid_mesh(H, W, 9, 11)
    x = X.copy()
    inner = (X[:, 0] > 0) & (X[:, 0] < W - 1) & (X[:, 1] > 0) & (X[:, 1] < H - 1)
    x[inner] += rng.uniform(-1.2, 1.2, (inner.sum(), 2))
    assert np.all(signed_areas(x, tris) > 0)
    tid, row, c0, length = render._scanline_spans(x, tris, H, W)
    flat = np.concatenate([r * W + np.arange(c, c + n) for r, c, n in zip(row, c0, length)])
    np.testing.assert_array_equal(np.bincount(flat, minlength=H * W), 1)
    alpha = render.warp_texture(np.ones((H, W)), X, x, tris, (H, W), supersample=1)[..., 3]
    np.testing.assert_array_equal(alpha, 1.0)


def test_no_fringe_from_transparent_texels():
    """Filtering happens on premultiplied colour: the (garbage) colour of transparent texels
    must not bleed into the straight colour of partly covered pixels."""
    tex = np.ones((8, 8, 4))
    tex[:, 4:, 3] = 0.0                                     # transparent white garbage
    tex[:, :4, :3] = 0.4                                    # opaque grey
    X, tris = grid_mesh(8, 8, 2, 2)
    for shift in (0.5, 0.3):
        out = render.warp_texture(tex, X, X + [shift, 0.0], tris, (8, 9), supersample=2)
        edge = out[4, 4]
        assert 0.2 < edge[3] < 0.9
        np.testing.assert_allclose(edge[:3], 0.4, atol=1e-5)
