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

from physlab._io import atomic_write_text
from physlab.mesh import TriMesh

from .rigging import FixedRig, WavyRig
from .strokes import EnergyStroke

__all__ = ["Material", "Body", "Scene"]


@dataclass
class Material:
    """Young's modulus ``E`` (per px²), Poisson ratio ``nu``, density ``rho`` (mass per px²)
    (PhysAnimator supp. Fig. 5: a larger ``E`` keeps its shape better)."""

    E: float = 2e5
    nu: float = 0.3
    rho: float = 1.0

    def __post_init__(self):
        if not (self.E > 0 and self.rho > 0 and -1 < self.nu < 0.5):
            raise ValueError(f"invalid material {self}: need E > 0, rho > 0, -1 < nu < 0.5")


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

    return iio.imread(io.BytesIO(base64.b64decode(text)), extension=".png")


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
            X, tris = self.mesh
            self.mesh = TriMesh(np.asarray(X, float), np.asarray(tris))

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
    def from_dict(cls, d):
        return cls(mesh=TriMesh(np.asarray(d["X"], float), np.asarray(d["tris"], dtype=np.int64)),
                   material=Material(**d["material"]),
                   texture=None if d.get("texture") is None else _decode_png(d["texture"]),
                   offset=tuple(d["offset"]), velocity=tuple(d["velocity"]), depth=d["depth"],
                   name=d["name"])


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
        if not self.bodies:
            raise ValueError("a scene needs at least one body")
        for r in self.rigs:
            if not 0 <= r.body < len(self.bodies):
                raise ValueError(f"rig refers to body {r.body}, but the scene has {len(self.bodies)}")

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
        """Inverse of :meth:`to_json` (JSON text or a file path)."""
        text = str(text_or_path)
        if not text.lstrip().startswith("{"):
            with open(text) as fh:
                text = fh.read()
        d = json.loads(text)
        rigs = []
        for r in d["rigs"]:
            r = dict(r)
            kind = r.pop("type")
            for key in ("center", "vertices", "direction"):
                if r.get(key) is not None:
                    r[key] = tuple(r[key])
            rigs.append({"FixedRig": FixedRig, "WavyRig": WavyRig}[kind](**r))
        return cls(bodies=[Body.from_dict(b) for b in d["bodies"]],
                   strokes=[EnergyStroke(**{**s, "direction": None if s.get("direction") is None
                                            else tuple(s["direction"])}) for s in d["strokes"]],
                   rigs=rigs,
                   gravity=tuple(d["gravity"]), ground=d["ground"],
                   walls=None if d["walls"] is None else tuple(d["walls"]),
                   collisions=d["collisions"], restitution=d["restitution"],
                   friction=d["friction"], damping=d["damping"], size=tuple(d["size"]))
