"""PhysAnimator scenes: bodies with materials and textures, energy strokes, rigs, contacts.

Coordinates are image pixels (x right, y DOWN), as for meshes built from drawings; time in
seconds. Gravity is therefore in px/s² and points along +y (e.g. ``(0, 980)`` makes
100 px behave like 1 m). Young's modulus ``E`` and density ``ρ`` are per px² (2D, unit
thickness), so the wave speed ``sqrt(E/ρ)`` is in px/s.
"""
from __future__ import annotations

import base64
import io
import json
from dataclasses import dataclass, field

import numpy as np

from physlab import _check
from physlab._io import atomic_write_text
from physlab.mesh import TriMesh

from .rigging import MAX_COORD, FixedRig, WavyRig
from .strokes import EnergyStroke

__all__ = ["Material", "Body", "Scene"]

#: Largest canvas side (px) a scene may have.
MAX_CANVAS = 16384
#: Largest scene file (bytes) :meth:`Scene.from_json` reads.
MAX_SCENE_BYTES = 512 * 1024**2


@dataclass
class Material:
    """Young's modulus ``E`` (per px²), Poisson ratio ``nu``, density ``rho`` (mass per px²)
    (PhysAnimator supp. Fig. 5: a larger ``E`` keeps its shape better)."""

    E: float = 2e5
    nu: float = 0.3
    rho: float = 1.0

    def __post_init__(self):
        self.E = _check.number(self.E, "Material E (Young's modulus)", lo=0, lo_open=True)
        self.rho = _check.number(self.rho, "Material rho (density)", lo=0, lo_open=True)
        self.nu = _check.number(self.nu, "Material nu (Poisson ratio)", lo=-1, hi=0.5,
                                lo_open=True, hi_open=True)


def _jsonable(obj):
    """numpy scalars and arrays in JSON (``json.dumps(default=...)``)."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serializable")


def _encode_png(image):
    import imageio.v3 as iio

    buf = io.BytesIO()
    iio.imwrite(buf, np.asarray(image), extension=".png")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _decode_png(text):
    import imageio.v3 as iio

    if not isinstance(text, str):
        raise TypeError(f"texture must be a base64 PNG string, got {type(text).__name__}")
    try:
        img = iio.imread(io.BytesIO(base64.b64decode(text, validate=True)), plugin="pillow")
    except Exception as e:  # noqa: BLE001 - base64 / PNG decoders raise many kinds
        raise ValueError(f"texture is not a valid base64 PNG ({type(e).__name__})") from None
    from physlab.image import as_float, to_uint8

    return to_uint8(as_float(img, "texture", channels=4))      # 8/16-bit, grey or RGB


@dataclass
class Body:
    """A deformable body: a triangle mesh in pixels, its material and its texture.

    ``mesh`` : :class:`physlab.mesh.TriMesh` (rest shape ``X`` in the texture's pixel frame);
    ``texture`` : optional RGBA uint8 image the mesh was cut from (used by the renderer);
    ``offset`` : (2,) translation of the body on the canvas at t = 0 (px);
    ``velocity`` : (2,) initial velocity (px/s); ``depth`` : drawing order (larger = further
    back); ``name`` : label.
    """

    mesh: TriMesh
    material: Material = field(default_factory=Material)
    texture: np.ndarray | None = None
    offset: tuple = (0.0, 0.0)
    velocity: tuple = (0.0, 0.0)
    depth: float = 0.0
    name: str = "body"

    def __post_init__(self):
        if not isinstance(self.mesh, TriMesh):
            try:
                X, tris = self.mesh                          # an (X, tris) pair
            except (TypeError, ValueError):
                raise TypeError(f"Body mesh must be a physlab.mesh.TriMesh or an (X, tris) "
                                f"pair, got {type(self.mesh).__name__}") from None
            self.mesh = TriMesh(_vertices(X), np.asarray(tris))
        if not isinstance(self.material, Material):
            raise TypeError(f"Body material must be a Material, got "
                            f"{type(self.material).__name__}")
        self.offset = tuple(_check.vector(self.offset, "Body offset").tolist())
        self.velocity = tuple(_check.vector(self.velocity, "Body velocity").tolist())
        far = np.abs(self.mesh.X).max(initial=0.0) + np.abs(self.offset).max()
        if far > MAX_COORD:
            raise ValueError(f"Body vertices must lie within ±{MAX_COORD:g} px of the canvas "
                             f"origin (mesh X + offset reaches {far:.3g} px); check the "
                             f"mesh units and the offset")
        if np.abs(self.velocity).max() > MAX_COORD:
            raise ValueError(f"Body velocity must be below {MAX_COORD:g} px/s, got "
                             f"{list(self.velocity)}")
        self.depth = _check.number(self.depth, "Body depth")
        if not isinstance(self.name, str):
            raise TypeError(f"Body name must be a string, got {self.name!r}")
        if self.texture is not None:
            t = np.asarray(self.texture)
            if t.ndim != 3 or t.shape[2] not in (3, 4) or t.dtype != np.uint8:
                raise ValueError(f"Body texture must be an (H, W, 3|4) uint8 image, got shape "
                                 f"{t.shape} and dtype {t.dtype}")

    @property
    def X_canvas(self):
        """Rest positions on the canvas (n, 2): ``X + offset``."""
        return self.mesh.X + np.asarray(self.offset, dtype=float)

    def to_dict(self):
        return dict(name=self.name, X=self.mesh.X.tolist(), tris=self.mesh.tris.tolist(),
                    material=self.material.__dict__, offset=list(self.offset),
                    velocity=list(self.velocity), depth=self.depth,
                    texture=None if self.texture is None else _encode_png(self.texture))

    @classmethod
    def from_dict(cls, d, where="body"):
        """Inverse of :meth:`to_dict`; ValueError naming the field (``where``) on bad data."""
        d = _fields(d, where, required=("X", "tris"),
                    optional=("name", "material", "offset", "velocity", "depth", "texture"))
        mesh = _at(f"{where}.X/tris", lambda: TriMesh(_vertices(_array(d["X"], float)),
                                                      _array(d["tris"], np.int64)))
        mat = _fields(d.get("material", {}), f"{where}.material",
                      optional=("E", "nu", "rho"))
        kw = {k: d[k] for k in ("offset", "velocity", "depth", "name") if k in d}
        tex = d.get("texture")
        if tex is not None:
            tex = _at(f"{where}.texture", lambda: _decode_png(tex))
        return _at(where, lambda: cls(mesh=mesh, material=Material(**mat), texture=tex, **kw))


def _vertices(X):
    """Mesh vertex positions (n, 2) px, finite and within ±MAX_COORD (checked before the mesh
    is built, so no area computation overflows)."""
    try:
        X = np.asarray(X, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("mesh X must be an (n, 2) array of numbers") from None
    if X.size and np.all(np.isfinite(X)) and np.abs(X).max() > MAX_COORD:
        raise ValueError(f"mesh X must lie within ±{MAX_COORD:g} px, got a vertex at "
                         f"{np.abs(X).max():.3g} px; check the mesh units")
    return X


def _array(value, dtype):
    """A JSON list as a numpy array of ``dtype``; integer fields must hold whole numbers."""
    a = np.asarray(value)
    if a.dtype == object or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
        raise ValueError("ragged or non-numeric list")
    if a.dtype == bool:
        raise ValueError("a list of numbers, got true/false values")
    if np.issubdtype(np.dtype(dtype), np.integer) and not np.issubdtype(a.dtype, np.integer):
        if a.size and not (np.all(np.isfinite(a)) and np.all(a == np.round(a))
                           and np.abs(a).max() < 2**62):
            raise ValueError("indices must be whole numbers")
    return a.astype(dtype)


def _fields(d, where, required=(), optional=()):
    """``d`` checked to be a JSON object with the ``required`` keys and no keys beyond
    ``required + optional``."""
    if not isinstance(d, dict):
        raise ValueError(f"field {where} must be a JSON object, got {type(d).__name__}")
    missing = [k for k in required if k not in d]
    if missing:
        raise ValueError(f"field {where} lacks {', '.join(repr(k) for k in missing)}")
    unknown = sorted(set(d) - set(required) - set(optional))
    if unknown:
        raise ValueError(f"field {where} has unknown key(s) {', '.join(map(repr, unknown))}; "
                         f"known: {', '.join(required + optional)}")
    return d


def _at(where, build):
    """``build()``, its ValueError / TypeError / KeyError re-raised naming the field."""
    try:
        return build()
    except (ValueError, TypeError, KeyError, IndexError) as e:
        msg = str(e)
        if msg.startswith(("bodies[", "strokes[", "rigs[")):     # already names its item
            msg = f"field {msg}"
        elif not msg.startswith("field "):
            msg = f"field {where}: {msg}"
        raise ValueError(msg) from None


def _scene_text(text_or_path):
    """``(source name, JSON text)`` of :meth:`Scene.from_json`'s argument: a path (str or
    PathLike) or JSON text (a str that starts like JSON)."""
    import os
    from pathlib import Path

    def is_file(path):
        try:
            return path.is_file()
        except (OSError, ValueError):               # name too long, NUL byte, ...
            return False

    if isinstance(text_or_path, str):
        text = text_or_path
        if text.lstrip()[:1] in ("{", "[") or "\n" in text:
            return "scene JSON", text
        path = Path(text)
        if not is_file(path):
            try:                                    # "42", "null", '"x"': JSON, not a path
                json.loads(text)
                return "scene JSON", text
            except (ValueError, RecursionError):
                pass
    elif isinstance(text_or_path, os.PathLike):
        path = Path(text_or_path)
    else:
        raise TypeError(f"Scene.from_json takes JSON text or a file path, got "
                        f"{type(text_or_path).__name__}")
    if not is_file(path):
        raise FileNotFoundError(f"no scene file {str(path)[:200]} (pass a path to a .json file "
                                f"written by Scene.to_json, or the JSON text itself)")
    size = path.stat().st_size
    if size > MAX_SCENE_BYTES:
        raise ValueError(f"{path}: {size / 1e6:.0f} MB is more than the limit of "
                         f"{MAX_SCENE_BYTES / 1e6:.0f} MB for a scene file; is it a scene?")
    try:
        return str(path), path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file; scene files are JSON") from None


@dataclass
class Scene:
    """Everything :func:`physlab.physanimator.simulate` needs.

    bodies : list of :class:`Body`; strokes : list of :class:`EnergyStroke` (canvas pixels);
    rigs : list of :class:`FixedRig` / :class:`WavyRig` (centres in the body's *canvas* rest
    frame); gravity : (2,) px/s² (y down); ground : y of a floor (px) or None;
    walls : (x_min, x_max) or None; collisions : body–body contacts on/off;
    restitution, friction : contact response; damping : mass-proportional velocity damping
    (1/s; ``-damping · m v``, not in the paper: it lets motions settle); size : canvas (W, H).
    """

    bodies: list
    strokes: list = field(default_factory=list)
    rigs: list = field(default_factory=list)
    gravity: tuple = (0.0, 0.0)
    ground: float | None = None
    walls: tuple | None = None
    collisions: bool = True
    restitution: float = 0.2
    friction: float = 0.3
    damping: float = 1.0
    size: tuple = (512, 512)

    def __post_init__(self):
        for name in ("bodies", "strokes", "rigs"):
            value = getattr(self, name)
            if not isinstance(value, (list, tuple)):
                raise TypeError(f"{name} must be a list, got {type(value).__name__}"
                                + (" (wrap a single Body in a list: [body])"
                                   if isinstance(value, Body) else ""))
            setattr(self, name, list(value))
        if not self.bodies:
            raise ValueError("a scene needs at least one body")
        for i, b in enumerate(self.bodies):
            if not isinstance(b, Body):
                raise TypeError(f"bodies[{i}] must be a Body, got {type(b).__name__}")
        for i, st in enumerate(self.strokes):
            if not isinstance(st, EnergyStroke):
                raise TypeError(f"strokes[{i}] must be an EnergyStroke, got {type(st).__name__}")
        for i, r in enumerate(self.rigs):
            if not isinstance(r, FixedRig):
                raise TypeError(f"rigs[{i}] must be a FixedRig or WavyRig, got "
                                f"{type(r).__name__}")
        self.gravity = tuple(_check.vector(self.gravity, "gravity").tolist())
        if self.ground is not None:
            self.ground = _check.number(self.ground, "ground", lo=-MAX_COORD, hi=MAX_COORD)
        if self.walls is not None:
            lo, hi = _check.vector(self.walls, "walls")
            if max(abs(lo), abs(hi)) > MAX_COORD:
                raise ValueError(f"walls must lie within ±{MAX_COORD:g} px, got {self.walls!r}")
            if not lo < hi:
                raise ValueError(f"walls must be (x_min, x_max) with x_min < x_max, got "
                                 f"{self.walls!r}")
            self.walls = (float(lo), float(hi))
        if not isinstance(self.collisions, (bool, np.bool_)):
            raise TypeError(f"collisions must be True or False, got {self.collisions!r}")
        self.restitution = _check.number(self.restitution, "restitution", lo=0, hi=1)
        self.friction = _check.number(self.friction, "friction", lo=0)
        self.damping = _check.number(self.damping, "damping", lo=0)
        w, h = _check.vector(self.size, "size")
        if not (1 <= w <= MAX_CANVAS and 1 <= h <= MAX_CANVAS and w == int(w) and h == int(h)):
            raise ValueError(f"size must be (W, H) whole pixels in 1..{MAX_CANVAS}, got "
                             f"{self.size!r}")
        self.size = (int(w), int(h))
        for i, b in enumerate(self.bodies):          # no body starts inside the ground / a wall
            X = b.X_canvas
            tol = 1e-6 * max(1.0, float(np.ptp(X, axis=0).max()) if len(X) else 1.0)
            for normal, c in self.half_planes():
                pen = c - X @ normal
                if pen.max(initial=-np.inf) > tol:
                    k = int(np.argmax(pen))
                    where = (f"below the ground (y = {X[k, 1]:.4g} px > ground = "
                             f"{self.ground:g} px; y points down)" if normal[1] else
                             f"outside the walls (x = {X[k, 0]:.4g} px, walls = "
                             f"{self.walls[0]:g}..{self.walls[1]:g} px)")
                    raise ValueError(f"bodies[{i}] ('{b.name}') starts {where} at vertex {k}; "
                                     f"move the body (offset) or the "
                                     f"{'ground' if normal[1] else 'walls'}")
        for i, r in enumerate(self.rigs):
            if not 0 <= r.body < len(self.bodies):
                raise ValueError(f"rigs[{i}] refers to body {r.body}, but the scene has "
                                 f"{len(self.bodies)} (indices 0..{len(self.bodies) - 1})")
            try:                                   # selects something on that body (cheap)
                r.select(self.bodies[r.body].X_canvas)
            except ValueError as e:
                raise ValueError(f"rigs[{i}] (on body {r.body}, "
                                 f"'{self.bodies[r.body].name}'): {e}") from None

    def half_planes(self):
        """Ground and walls as half-planes ``(normal, c)`` with ``normal · x >= c`` allowed."""
        planes = []
        if self.ground is not None:
            planes.append((np.array([0.0, -1.0]), -float(self.ground)))  # y <= ground (y down)
        if self.walls is not None:
            planes.append((np.array([1.0, 0.0]), float(self.walls[0])))
            planes.append((np.array([-1.0, 0.0]), -float(self.walls[1])))
        return planes

    # ------------------------------------------------------------------ JSON
    def to_dict(self):
        return dict(
            bodies=[b.to_dict() for b in self.bodies],
            strokes=[s.to_dict() for s in self.strokes],
            rigs=[r.to_dict() for r in self.rigs],
            gravity=list(self.gravity), ground=self.ground,
            walls=None if self.walls is None else list(self.walls),
            collisions=self.collisions, restitution=self.restitution, friction=self.friction,
            damping=self.damping, size=list(self.size))

    def to_json(self, path=None):
        """The scene as JSON text (textures as base64 PNG); also written to ``path`` if given."""
        text = json.dumps(self.to_dict(), default=_jsonable)
        if path is not None:
            atomic_write_text(path, text)
        return text

    @classmethod
    def from_json(cls, text_or_path):
        """Inverse of :meth:`to_json`: JSON text or a file path.

        FileNotFoundError for a missing file; ValueError naming the file (or "scene JSON")
        and the field for invalid JSON, a missing or unknown key, a wrong type, an unknown
        rig / stroke kind, a non-finite or out-of-range value or a corrupt texture."""
        source, text = _scene_text(text_or_path)
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"{source}: not valid JSON (line {e.lineno}, column {e.colno}: "
                             f"{e.msg}); is the file truncated?") from None
        except RecursionError:
            raise ValueError(f"{source}: not valid JSON for a scene: lists or objects nested "
                             f"too deeply") from None
        try:
            return cls.from_dict(d)
        except ValueError as e:
            raise ValueError(f"{source}: {e}") from None

    @classmethod
    def from_dict(cls, d):
        """Inverse of :meth:`to_dict`; ValueError naming the field on bad data."""
        d = _fields(d, "scene", required=("bodies",),
                    optional=("strokes", "rigs", "gravity", "ground", "walls", "collisions",
                              "restitution", "friction", "damping", "size"))
        lists = {}
        for key in ("bodies", "strokes", "rigs"):
            lists[key] = d.get(key, [])
            if not isinstance(lists[key], list):
                raise ValueError(f"field {key} must be a JSON list, got "
                                 f"{type(lists[key]).__name__}")
        bodies = [Body.from_dict(b, f"bodies[{i}]") for i, b in enumerate(lists["bodies"])]
        strokes = []
        for i, st in enumerate(lists["strokes"]):
            where = f"strokes[{i}]"
            st = _fields(st, where, required=("points",),
                         optional=("kind", "strength", "range", "speed", "start",
                                   "n_particles", "loop", "direction"))
            strokes.append(_at(where, lambda st=st: EnergyStroke(**st)))
        rigs = []
        kinds = {"FixedRig": FixedRig, "WavyRig": WavyRig}
        for i, r in enumerate(lists["rigs"]):
            where = f"rigs[{i}]"
            r = dict(_fields(r, where, required=("type",),
                             optional=("body", "center", "radius", "vertices", "amplitude",
                                       "frequency", "direction")))
            kind = r.pop("type")
            if not isinstance(kind, str) or kind not in kinds:
                raise ValueError(f"field {where}.type: unknown rig kind {kind!r}; expected "
                                 f"{' or '.join(kinds)}")
            if kind == "FixedRig" and {"amplitude", "frequency", "direction"} & set(r):
                raise ValueError(f"field {where}: a FixedRig has no amplitude / frequency / "
                                 f"direction (use type WavyRig)")
            rigs.append(_at(where, lambda r=r, kind=kind: kinds[kind](**r)))
        top = {k: d[k] for k in ("gravity", "ground", "walls", "collisions", "restitution",
                                 "friction", "damping", "size") if k in d}
        return _at("scene", lambda: cls(bodies=bodies, strokes=strokes, rigs=rigs, **top))
