"""Sample drawings the project makes itself, and loaders for external real data.

Procedural drawings
-------------------
:func:`cartoon_ball`, :func:`cartoon_tree`, :func:`cartoon_flag` and :func:`jelly_character`
paint small cartoon objects as RGBA uint8 images ``(size, size, 4)``: a transparent
background, near-black ink outlines a few pixels wide, flat colours with simple shading, and a
texture (spots, stripes, hatching, bubbles) so that a texture warped by a deforming mesh
visibly moves. They are deterministic given ``seed`` and need no files, so lessons and
library defaults work on a fresh clone. Shapes are painted from signed distance fields
(negative inside, in px), which gives antialiased edges: a pixel's coverage is
``clip(0.5 - sdf, 0, 1)``.

Each function returns a :class:`Drawing` with suggested pins (points to hold fixed or rig)
in pixel coordinates ``(x, y)``, y down (pixel ``image[i, j]`` is centred at ``(j, i)``).

External data
-------------
:func:`external_data_dir` finds the shared folder of real data (never copied into the
repository; see ``../shared/data/README.md``) and :func:`animated_drawing` reads one of the
six AnimatedDrawings example characters. Attribution: AnimatedDrawings, MIT,
© Meta Platforms, Inc. and affiliates (facebookresearch/AnimatedDrawings).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .paint import INK, Canvas as _Canvas, box_sdf as _box_sdf, circle_sdf as _circle_sdf
from .paint import ellipse_sdf as _ellipse_sdf, fill as _fill, lines as _lines
from .paint import polygon_sdf as _polygon_sdf, shade as _shade, stroke as _stroke


__all__ = [
    "Drawing",
    "cartoon_ball",
    "cartoon_tree",
    "cartoon_flag",
    "jelly_character",
    "sample_drawings",
    "SAMPLE_DRAWINGS",
    "external_data_dir",
    "animated_drawing",
    "ANIMATED_DRAWINGS",
    "ANIMATED_DRAWINGS_ATTRIBUTION",
]

#: Names of the AnimatedDrawings example characters.
ANIMATED_DRAWINGS = ("char1", "char2", "char3", "char4", "char5", "char6")
ANIMATED_DRAWINGS_ATTRIBUTION = ("AnimatedDrawings example characters, MIT licence, © Meta "
                                 "Platforms, Inc. and affiliates (facebookresearch/AnimatedDrawings)")


@dataclass(frozen=True, eq=False)
class Drawing:
    """A drawing to animate.

    Attributes
    ----------
    name : str.
    image : (H, W, 4) uint8 RGBA image (alpha 0 = background).
    pins : (k, 2) float64, suggested fixed / rigging points ``(x, y)`` in pixels (y down);
        ``(0, 2)`` when there are none.
    notes : dict, extra information (what the pins are, parts of the drawing, licence, and
        for real drawings the skeleton and mask).
    """

    name: str
    image: np.ndarray
    pins: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    notes: dict = field(default_factory=dict)

    def __post_init__(self):
        img = np.asarray(self.image)
        if img.ndim != 3 or img.shape[2] != 4 or img.dtype != np.uint8:
            raise ValueError(f"image must be an (H, W, 4) uint8 RGBA array, got {img.dtype} "
                             f"{img.shape}")
        pins = np.asarray(self.pins, dtype=np.float64).reshape(-1, 2)
        object.__setattr__(self, "pins", pins)

    def __repr__(self):
        h, w = self.image.shape[:2]
        return f"Drawing(name={self.name!r}, image={h}x{w} RGBA, pins={len(self.pins)})"


def _rng_color(rng, palette):
    return np.asarray(palette[rng.integers(len(palette))], dtype=float)


def _check_size(size):
    size = int(size)
    if size < 32:
        raise ValueError(f"size must be >= 32 px, got {size}")
    return size


# ---------------------------------------------------------------------------------- drawings
def cartoon_ball(size=256, seed=0):
    """A shaded ball with polka dots, a highlight and an ink outline.

    Returns
    -------
    Drawing "ball": ``image`` (size, size, 4) uint8; no pins (a free body);
    ``notes`` = {"center": (x, y), "radius": r} in px.
    """
    size = _check_size(size)
    rng = np.random.default_rng(seed)
    cv = _Canvas(size)
    s = size / 256
    cx, cy = size / 2 + rng.uniform(-6, 6) * s, size / 2 + rng.uniform(-6, 6) * s
    r = size * rng.uniform(0.32, 0.37)
    ink_w = max(2.0, 4.0 * s)
    base = _rng_color(rng, [(0.90, 0.25, 0.20), (0.20, 0.55, 0.90), (0.95, 0.70, 0.15),
                            (0.35, 0.75, 0.35)])
    dot = _rng_color(rng, [(1.0, 0.97, 0.85), (0.98, 0.92, 0.35), (0.85, 0.95, 1.0)])
    ball = _circle_sdf(cv, cx, cy, r)
    cv.paint(_fill(ball), _shade(cv, cx, cy, r, base))
    # polka dots: rejection-sampled centres inside the ball, clipped to it
    n_dots = 14
    ang = rng.uniform(0, 2 * np.pi, n_dots)
    rad = r * np.sqrt(rng.uniform(0.0, 0.85, n_dots))
    dr = r * rng.uniform(0.07, 0.13, n_dots)
    dots = np.min([_circle_sdf(cv, cx + q * np.cos(a), cy + q * np.sin(a), d)
                   for a, q, d in zip(ang, rad, dr)], axis=0)
    cv.paint(_fill(np.maximum(dots, ball)), _shade(cv, cx, cy, r, dot, 0.2))
    # a curved seam stripe (arc of a larger circle) and a highlight
    seam = np.abs(_circle_sdf(cv, cx + 1.3 * r, cy + 0.4 * r, 1.45 * r)) - 2.5 * s
    cv.paint(_fill(np.maximum(seam, ball)), INK)
    hl = _ellipse_sdf(cv, cx - 0.42 * r, cy - 0.45 * r, 0.18 * r, 0.11 * r)
    cv.paint(0.85 * _fill(hl), (1.0, 1.0, 1.0))
    cv.paint(_stroke(ball - ink_w / 2, ink_w), INK)  # outline just inside the rim
    return Drawing("ball", cv.image(), np.zeros((0, 2)),
                   {"center": (float(cx), float(cy)), "radius": float(r),
                    "pins": "none: the ball is a free body"})


def cartoon_tree(size=256, seed=0):
    """A tree: a brown trunk with bark hatching and a crown of overlapping leaf blobs.

    Trunk and crown overlap, so the drawing is one connected body.

    Returns
    -------
    Drawing "tree": pins (3, 2) along the base of the trunk (left, centre, right, 3 px
    above its bottom edge); ``notes`` has "trunk" (polygon (4, 2)) and "crown_circles"
    (c, 3) of (x, y, r).
    """
    size = _check_size(size)
    rng = np.random.default_rng(seed)
    cv = _Canvas(size)
    s = size / 256
    ink_w = max(2.0, 3.5 * s)
    cx = size / 2 + rng.uniform(-5, 5) * s
    base_y, top_y = size * 0.93, size * 0.45
    wb, wt = size * 0.085, size * 0.05  # half widths at base and top
    trunk = np.array([[cx - wb, base_y], [cx + wb, base_y], [cx + wt, top_y], [cx - wt, top_y]])
    trunk_sdf = _polygon_sdf(cv, trunk)
    # crown: a ring of blobs around a central one
    ccx, ccy, cr = cx, size * 0.36, size * 0.27
    k = 7
    ang = -np.pi / 2 + np.linspace(0, 2 * np.pi, k, endpoint=False) + rng.uniform(-0.2, 0.2, k)
    blobs = np.concatenate([
        np.stack([ccx + 0.62 * cr * np.cos(ang), ccy + 0.55 * cr * np.sin(ang),
                  cr * rng.uniform(0.36, 0.46, k)], axis=1),
        [[ccx, ccy, 0.62 * cr]]])
    blobs[:, 1] = np.minimum(blobs[:, 1], size * 0.62)  # keep the crown above the trunk base
    crown_sdf = np.min([_circle_sdf(cv, bx, by, br) for bx, by, br in blobs], axis=0)
    bark = np.array([0.50, 0.32, 0.17])
    cv.paint(_fill(trunk_sdf), _shade(cv, cx, (base_y + top_y) / 2, size * 0.2, bark, 0.25))
    # bark hatching: a few wavy vertical strokes inside the trunk
    ys = np.linspace(top_y, base_y, 12)
    segs = []
    for f in np.linspace(-0.6, 0.6, 4):
        half = wt + (wb - wt) * (ys - top_y) / (base_y - top_y)  # trunk half width at ys
        xs = cx + f * half + 1.5 * s * np.sin(ys / (7 * s) + f * 3)
        segs += [(xs[i], ys[i], xs[i + 1], ys[i + 1]) for i in range(len(ys) - 1)]
    cv.paint(0.8 * _lines(cv, segs) * _fill(trunk_sdf + 2), INK)
    cv.paint(_stroke(trunk_sdf, ink_w) * (crown_sdf > 0), INK)
    leaf = _rng_color(rng, [(0.30, 0.65, 0.25), (0.40, 0.72, 0.30), (0.25, 0.58, 0.35)])
    cv.paint(_fill(crown_sdf), _shade(cv, ccx, ccy, cr, leaf, 0.4))
    # leaf texture: darker small leaf spots and light specks, clipped to the crown
    n = 40
    px, py = ccx + cr * rng.uniform(-1, 1, n), ccy + cr * rng.uniform(-0.9, 0.9, n)
    spots = np.min([_ellipse_sdf(cv, a, b, 5 * s, 3 * s) for a, b in zip(px, py)], axis=0)
    cv.paint(_fill(np.maximum(spots, crown_sdf + 1)), leaf * 0.62)
    # inner blob outlines (thin), so the crown reads as a bunch of leaf clusters
    for bx, by, br in blobs[:-1]:
        arc = _stroke(_circle_sdf(cv, bx, by, br), 1.2 * s) * (cv.y > by) * (crown_sdf < -2)
        cv.paint(0.7 * arc, leaf * 0.45)
    cv.paint(_stroke(crown_sdf, ink_w), INK)
    pins = np.array([[cx - 0.7 * wb, base_y - 3], [cx, base_y - 3], [cx + 0.7 * wb, base_y - 3]])
    return Drawing("tree", cv.image(), pins,
                   {"trunk": trunk, "crown_circles": blobs,
                    "pins": "base of the trunk (fix these to plant the tree)"})


def cartoon_flag(size=256, seed=0):
    """A flag on a pole: striped cloth with an emblem, attached to the pole's right side.

    Returns
    -------
    Drawing "flag": pins (8, 2) on the pole's centre line, from the top of the cloth to
    the bottom of the pole (fix them: the pole is rigid); ``notes`` has "pole"
    (x0, y0, x1, y1) and "cloth" (x0, y0, x1, y1) boxes in px.
    """
    size = _check_size(size)
    rng = np.random.default_rng(seed)
    cv = _Canvas(size)
    s = size / 256
    ink_w = max(2.0, 3.5 * s)
    px0, px1 = size * 0.18, size * 0.18 + max(8.0, 10 * s)
    py0, py1 = size * 0.10, size * 0.95
    cloth = (px1 - ink_w / 2, size * 0.14, size * 0.86, size * 0.14 + size * rng.uniform(0.36, 0.42))
    pole_sdf = _box_sdf(cv, px0, py0, px1, py1)
    cloth_sdf = _box_sdf(cv, *cloth)
    union = np.minimum(pole_sdf, cloth_sdf)
    c1, c2 = (_rng_color(rng, [(0.85, 0.15, 0.2), (0.15, 0.35, 0.8), (0.1, 0.6, 0.35)]),
              np.array([0.97, 0.95, 0.88]))
    # horizontal stripes
    n_stripes = 6
    t = (cv.y - cloth[1]) / (cloth[3] - cloth[1])
    stripes = np.where((np.floor(t * n_stripes) % 2) == 0, 1.0, 0.0)[..., None]
    col = stripes * c1 + (1 - stripes) * c2
    # cloth shading: soft vertical folds
    fold = 1.0 + 0.12 * np.sin((cv.x - cloth[0]) / (cloth[2] - cloth[0]) * 2 * np.pi * 2.5)
    cv.paint(_fill(cloth_sdf), np.clip(col * fold[..., None], 0, 1))
    # emblem: a circle with a star-like dot pattern in the canton
    ex, ey = cloth[0] + 0.28 * (cloth[2] - cloth[0]), (cloth[1] + cloth[3]) / 2
    er = 0.3 * (cloth[3] - cloth[1])
    emblem = _circle_sdf(cv, ex, ey, er)
    cv.paint(_fill(emblem), (0.98, 0.80, 0.15))
    cv.paint(_stroke(emblem, 2 * s), INK)
    ang = np.linspace(0, 2 * np.pi, 6, endpoint=False) + rng.uniform(0, 1)
    pts = np.min([_circle_sdf(cv, ex + 0.55 * er * np.cos(a), ey + 0.55 * er * np.sin(a), 0.13 * er)
                  for a in ang], axis=0)
    cv.paint(_fill(pts), c1 * 0.8)
    # pole: wood with a highlight stripe, gold ball on top
    wood = np.array([0.55, 0.42, 0.30])
    cv.paint(_fill(pole_sdf), _shade(cv, (px0 + px1) / 2, (py0 + py1) / 2, (px1 - px0), wood, 0.3))
    knob = _circle_sdf(cv, (px0 + px1) / 2, py0, 0.9 * (px1 - px0))
    cv.paint(_fill(knob), _shade(cv, (px0 + px1) / 2, py0, 0.9 * (px1 - px0), (0.95, 0.75, 0.2), 0.4))
    union = np.minimum(union, knob)
    cv.paint(_stroke(union, ink_w), INK)
    cv.paint(_stroke(pole_sdf, ink_w) * (cloth_sdf < 0) * (pole_sdf > -ink_w), INK)  # seam
    xc = (px0 + px1) / 2
    pins = np.stack([np.full(8, xc), np.linspace(cloth[1] + 2, py1 - 3, 8)], axis=1)
    return Drawing("flag", cv.image(), pins,
                   {"pole": (float(px0), float(py0), float(px1), float(py1)),
                    "cloth": tuple(float(c) for c in cloth),
                    "pins": "centre line of the pole (fix these: the pole is rigid)"})


def jelly_character(size=256, seed=0):
    """A jelly blob character: wobbly dome body, bubbles, highlight, eyes and a smile.

    Returns
    -------
    Drawing "jelly": pins (3, 2) along the bottom of the body (where it sits on the
    ground); ``notes`` has "center" (x, y), "radius" and "eyes" (2, 2) in px.
    """
    size = _check_size(size)
    rng = np.random.default_rng(seed)
    cv = _Canvas(size)
    s = size / 256
    ink_w = max(2.0, 4.0 * s)
    cx, cy = size / 2, size * 0.56
    R = size * 0.36
    # body: a wobbly superellipse-like dome, flatter at the bottom (y down)
    dx, dy = cv.x - cx, cv.y - cy
    th = np.arctan2(dy, dx)
    ph = rng.uniform(0, 2 * np.pi, 3)
    wob = 1 + 0.05 * np.sin(3 * th + ph[0]) + 0.03 * np.sin(5 * th + ph[1])
    ry = np.where(dy > 0, 0.62 * R, 0.9 * R)  # squashed below the centre
    q = np.hypot(dx / (1.02 * R), dy / ry)
    body = (q / wob - 1.0) * 0.7 * R  # ≈ SDF near the boundary
    base = _rng_color(rng, [(0.45, 0.85, 0.55), (0.95, 0.50, 0.70), (0.55, 0.70, 0.98),
                            (0.98, 0.72, 0.35)])
    shade = _shade(cv, cx, cy - 0.2 * R, R, base, 0.45)
    cv.paint(_fill(body), shade)
    # diagonal stripes (jelly layers) and bubbles, clipped to the body
    stripes = (np.sin((cv.x + cv.y) / (9 * s)) > 0.55) * _fill(body + 3)
    cv.paint(0.35 * stripes, np.clip(base * 0.7, 0, 1))
    n = 12
    bx, by = cx + R * rng.uniform(-0.7, 0.7, n), cy + R * rng.uniform(-0.2, 0.45, n)
    br = R * rng.uniform(0.03, 0.08, n)
    bub = np.min([_circle_sdf(cv, a, b, r) for a, b, r in zip(bx, by, br)], axis=0)
    cv.paint(0.6 * _fill(np.maximum(bub, body + 3)), (1.0, 1.0, 1.0))
    highlight = _ellipse_sdf(cv, cx - 0.5 * R, cy - 0.55 * R, 0.16 * R, 0.08 * R)
    cv.paint(0.9 * _fill(highlight), (1.0, 1.0, 1.0))
    # face
    eyes = np.array([[cx - 0.3 * R, cy - 0.28 * R], [cx + 0.3 * R, cy - 0.28 * R]])
    for ex, ey in eyes:
        white = _ellipse_sdf(cv, ex, ey, 0.13 * R, 0.17 * R)
        cv.paint(_fill(white), (1.0, 1.0, 1.0))
        cv.paint(_stroke(white, 2 * s), INK)
        cv.paint(_fill(_circle_sdf(cv, ex + 0.03 * R, ey + 0.04 * R, 0.07 * R)), INK)
        cv.paint(_fill(_circle_sdf(cv, ex + 0.0, ey - 0.01 * R, 0.025 * R)), (1.0, 1.0, 1.0))
    mouth = np.abs(_circle_sdf(cv, cx, cy - 0.25 * R, 0.35 * R)) - 1.6 * s
    cv.paint(_fill(mouth) * (cv.y > cy - 0.0 * R), INK)
    cv.paint(_stroke(body - ink_w / 2, ink_w), INK)
    # pins: the lowest body pixel of three columns, moved up to lie well inside the outline
    cols = np.round([cx - 0.4 * R, cx, cx + 0.4 * R]).astype(int)
    inside = body[:, cols] < -2 * ink_w  # (H, 3)
    rows = size - 1 - np.argmax(inside[::-1], axis=0)
    pins = np.stack([cols, rows], axis=1).astype(float)
    return Drawing("jelly", cv.image(), pins,
                   {"center": (float(cx), float(cy)), "radius": float(R), "eyes": eyes,
                    "pins": "bottom of the body (where it sits on the ground)"})


#: Name → builder of the procedural drawings.
SAMPLE_DRAWINGS = {"ball": cartoon_ball, "tree": cartoon_tree, "flag": cartoon_flag,
                   "jelly": jelly_character}


def sample_drawings(size=256, seed=0):
    """All procedural drawings: dict name → :class:`Drawing` ("ball", "tree", "flag", "jelly")."""
    return {name: make(size=size, seed=seed) for name, make in SAMPLE_DRAWINGS.items()}


# ---------------------------------------------------------------------------------- external data
def external_data_dir():
    """The folder of external real data, or None when it is not available.

    ``$PHYSLAB_EXTERNAL_DATA`` if set and an existing folder, else ``<repo root>/../shared/data``
    (repo root = the folder holding the ``physlab`` package) if it exists, else None.
    """
    env = os.environ.get("PHYSLAB_EXTERNAL_DATA")
    if env and Path(env).expanduser().is_dir():
        return Path(env).expanduser().resolve()
    default = Path(__file__).resolve().parent.parent.parent / "shared" / "data"
    return default.resolve() if default.is_dir() else None


def _read_yaml(path):
    import yaml

    with open(path, encoding="utf-8") as f:
        return yaml.safe_load(f)


def animated_drawing(name):
    """One of the AnimatedDrawings example characters (real amateur drawings).

    Reads ``animated_drawings/examples/characters/<name>/`` of :func:`external_data_dir`:
    ``texture.png`` (RGB or RGBA photo of the drawing; returned as RGBA), ``mask.png``
    (0/255 foreground mask) and ``char_cfg.yaml`` (2D skeleton in pixels).

    Parameters
    ----------
    name : one of :data:`ANIMATED_DRAWINGS` ("char1" … "char6").

    Returns
    -------
    Drawing with ``image`` (H, W, 4) uint8, ``pins`` (J, 2) the skeleton joint positions
    (pixels, y down; the rigging points), and ``notes``:

    * "skeleton": {"names": list of J str, "parents": (J,) int64 with -1 for the root,
      "xy": (J, 2) float64 pixels} — the arguments of ``physlab.inbetween.Skeleton``;
    * "mask": (H, W) bool, the provided foreground mask;
    * "char_cfg": the raw YAML dict; "path": the folder; "attribution": licence line.

    Raises
    ------
    FileNotFoundError if the external data folder or the character is missing.
    """
    import imageio.v3 as iio

    from .mesh import mask_from_array

    if name not in ANIMATED_DRAWINGS:
        raise ValueError(f"unknown AnimatedDrawings character {name!r}; choose one of "
                         f"{ANIMATED_DRAWINGS}")
    root = external_data_dir()
    if root is None:
        raise FileNotFoundError(
            "the external data folder was not found: set PHYSLAB_EXTERNAL_DATA to the folder that "
            "holds animated_drawings/ (or place it at <repo root>/../shared/data)")
    folder = root / "animated_drawings" / "examples" / "characters" / name
    files = {k: folder / f for k, f in
             (("texture", "texture.png"), ("mask", "mask.png"), ("cfg", "char_cfg.yaml"))}
    missing = [str(p) for p in files.values() if not p.is_file()]
    if missing:
        raise FileNotFoundError(f"AnimatedDrawings character {name!r} is incomplete in {root}: "
                                f"missing {', '.join(missing)}")
    tex = np.asarray(iio.imread(files["texture"]))
    if tex.ndim == 2:
        tex = np.repeat(tex[..., None], 3, axis=2)
    if tex.dtype != np.uint8:
        raise ValueError(f"{files['texture']}: expected 8-bit image, got {tex.dtype}")
    if tex.shape[2] == 3:
        tex = np.concatenate([tex, np.full(tex.shape[:2] + (1,), 255, np.uint8)], axis=2)
    mask = mask_from_array(iio.imread(files["mask"]))
    if mask.shape != tex.shape[:2]:
        raise ValueError(f"{name}: mask {mask.shape} and texture {tex.shape[:2]} differ in size")
    cfg = _read_yaml(files["cfg"])
    joints = cfg["skeleton"]
    names = [str(j["name"]) for j in joints]
    index = {n: i for i, n in enumerate(names)}
    parents = np.array([-1 if j.get("parent") is None else index[j["parent"]] for j in joints],
                       dtype=np.int64)
    xy = np.array([j["loc"] for j in joints], dtype=np.float64).reshape(-1, 2)
    return Drawing(name, tex, xy,
                   {"skeleton": {"names": names, "parents": parents, "xy": xy}, "mask": mask,
                    "char_cfg": cfg, "path": str(folder),
                    "attribution": ANIMATED_DRAWINGS_ATTRIBUTION})


# ---------------------------------------------------------------------------------- characters
#: The procedural characters moved to :mod:`physlab.inbetween.characters` (next to the skeleton
#: they draw); their old names here keep working for one release, with a DeprecationWarning.
_MOVED = ("ADJACENT_PARTS", "CHARACTER_JOINTS", "CHARACTER_PARTS", "CHARACTER_STYLES",
          "PAINT_ORDER", "InbetweenPair", "character_part_labels", "character_skeleton",
          "inbetween_benchmark", "part_overlaps", "pose_character", "render_character")


def __getattr__(name):
    if name in _MOVED:
        import warnings

        warnings.warn(f"physlab.datasets.{name} moved to physlab.inbetween.characters.{name} "
                      f"(also physlab.inbetween.{name}); the old name goes in the next release",
                      DeprecationWarning, stacklevel=2)
        from .inbetween import characters

        return getattr(characters, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
