"""physlab.datasets: procedural drawings and the external-data loader."""
import numpy as np
import pytest
from scipy import ndimage as ndi

from physlab import datasets, mesh
from physlab.datasets import Drawing

NAMES = tuple(datasets.SAMPLE_DRAWINGS)


@pytest.fixture(scope="module")
def drawings():
    return datasets.sample_drawings()


def luminance(rgb):
    return rgb[..., :3].astype(float) @ [0.2125, 0.7154, 0.0721] / 255


@pytest.mark.parametrize("size", [96, 256])
@pytest.mark.parametrize("name", NAMES)
def test_drawing_format_background_and_foreground(name, size):
    d = datasets.SAMPLE_DRAWINGS[name](size=size)
    assert isinstance(d, Drawing) and d.name == name
    assert d.image.shape == (size, size, 4) and d.image.dtype == np.uint8
    a = d.image[..., 3]
    border = np.concatenate([a[0], a[-1], a[:, 0], a[:, -1]])
    assert np.all(border == 0)  # transparent background reaches the image edge
    opaque = (a == 255).mean()
    assert 0.1 < opaque < 0.7  # a body of reasonable size
    partial = (a > 0) & (a < 255)
    assert partial.any()  # antialiased edges ...
    assert not np.any(partial & ~ndi.binary_dilation(a == 255, iterations=2))  # ... only at edges
    assert d.pins.ndim == 2 and d.pins.shape[1] == 2 and d.pins.dtype == np.float64


@pytest.mark.parametrize("name", NAMES)
def test_drawings_are_deterministic_per_seed(name):
    make = datasets.SAMPLE_DRAWINGS[name]
    a, b, c = make(size=128, seed=3), make(size=128, seed=3), make(size=128, seed=4)
    np.testing.assert_array_equal(a.image, b.image)
    np.testing.assert_array_equal(a.pins, b.pins)
    assert not np.array_equal(a.image, c.image)


@pytest.mark.parametrize("name", NAMES)
def test_drawings_have_ink_outline_and_texture(drawings, name):
    img = drawings[name].image
    fg = img[..., 3] == 255
    rim = fg & ~ndi.binary_erosion(fg, iterations=2)
    L = luminance(img)
    assert np.median(L[rim]) < 0.2  # near-black ink along the outline
    inner = ndi.binary_erosion(fg, iterations=6)
    assert L[inner].std() > 0.08  # shading + pattern, not a flat fill
    hist = np.unique((img[inner][:, :3] // 32), axis=0)
    assert len(hist) >= 6  # several distinct colours inside


@pytest.mark.parametrize("name", NAMES)
def test_drawing_gives_one_valid_mesh_with_pins_inside(drawings, name):
    d = drawings[name]
    fm = mesh.foreground_mask(d.image)
    alpha = d.image[..., 3] > 127
    assert (fm & alpha).sum() / (fm | alpha).sum() > 0.995  # alpha path (+ a 2-px closing)
    assert len(mesh.mask_components(fm)) == 1  # a single body
    me = mesh.mesh_from_mask(fm)
    assert me.is_positively_oriented and me.min_angle() >= 19.9
    assert me.area == pytest.approx(fm.sum(), rel=0.05)
    assert 100 <= me.n_tris <= 1000
    assert np.all(mesh.point_in_mesh(me, d.pins))
    # pins can become mesh vertices (e.g. to fix them)
    me_p = mesh.mesh_from_mask(fm, points=d.pins)
    assert np.all(mesh.vertex_indices(me_p, d.pins) >= 0)


def test_pins_match_the_drawn_parts(drawings):
    assert len(drawings["ball"].pins) == 0
    x0, y0, x1, y1 = drawings["flag"].notes["pole"]
    p = drawings["flag"].pins
    assert np.all((p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 1] > y0) & (p[:, 1] < y1))
    tree = drawings["tree"].pins
    assert tree[:, 1].min() > 0.85 * 256  # at the bottom of the trunk (y down)
    jelly = drawings["jelly"]
    assert np.all(jelly.pins[:, 1] > jelly.notes["center"][1])  # below the centre (y down)


def test_drawing_validates_image():
    with pytest.raises(ValueError, match="RGBA"):
        Drawing("x", np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(ValueError, match="size"):
        datasets.cartoon_ball(size=8)


# ---------------------------------------------------------------------------------- external data
def test_external_data_dir_env_override(tmp_path, monkeypatch):
    monkeypatch.setenv("PHYSLAB_EXTERNAL_DATA", str(tmp_path))
    assert datasets.external_data_dir() == tmp_path.resolve()
    with pytest.raises(FileNotFoundError, match="char1"):
        datasets.animated_drawing("char1")  # folder exists but holds no characters
    monkeypatch.setenv("PHYSLAB_EXTERNAL_DATA", str(tmp_path / "missing"))
    d = datasets.external_data_dir()  # falls back to <repo root>/../shared/data, or None
    assert d is None or d.name == "data"


def test_missing_external_data_raises_clear_error(monkeypatch):
    monkeypatch.setattr(datasets, "external_data_dir", lambda: None)
    with pytest.raises(FileNotFoundError, match="PHYSLAB_EXTERNAL_DATA"):
        datasets.animated_drawing("char1")
    with pytest.raises(ValueError, match="char1"):
        datasets.animated_drawing("char7")


@pytest.mark.parametrize("name", datasets.ANIMATED_DRAWINGS)
def test_animated_drawing_loads(real_data, name):
    d = datasets.animated_drawing(name)
    h, w = d.image.shape[:2]
    assert d.image.dtype == np.uint8 and d.image.shape[2] == 4
    assert d.notes["mask"].shape == (h, w) and d.notes["mask"].dtype == bool
    assert 0.1 < d.notes["mask"].mean() < 0.9
    sk = d.notes["skeleton"]
    J = len(sk["names"])
    assert sk["xy"].shape == (J, 2) and sk["parents"].shape == (J,)
    assert np.sum(sk["parents"] == -1) == 1 and np.all(sk["parents"] < J)
    assert np.all((sk["xy"] >= 0) & (sk["xy"] <= [w, h]))  # (x, y) pixels inside the image
    np.testing.assert_array_equal(d.pins, sk["xy"])
    # joints lie on the drawing: mask at (row = y, col = x)
    ij = np.clip(np.round(sk["xy"][:, ::-1]).astype(int), 0, [h - 1, w - 1])
    assert d.notes["mask"][ij[:, 0], ij[:, 1]].mean() > 0.8
    assert "Meta" in d.notes["attribution"]


def test_animated_drawing_char1_reference(real_data):
    d = datasets.animated_drawing("char1")
    assert d.image.shape == (602, 508, 4)
    sk = d.notes["skeleton"]
    assert len(sk["names"]) == 16 and sk["names"][0] == "root"
    np.testing.assert_array_equal(sk["xy"][sk["names"].index("neck")], [231, 119])
    assert sk["names"][sk["parents"][sk["names"].index("left_hand")]] == "left_elbow"
