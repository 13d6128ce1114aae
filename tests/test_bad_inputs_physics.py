"""Bad input to the physics half (integrators, springs, FEM, PhysAnimator scenes): each case
raises an error that blames the right cause — the argument or field, never "use a smaller
dt" for a NaN parameter — and a blow-up is caught by its growth, not only by NaN."""
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from physlab import fem, springs
from physlab import physanimator as pa
from physlab.integrators import SimulationDiverged, integrate, simulate
from physlab.mesh import grid_mesh


def test_a_blow_up_is_caught_by_growth_and_names_the_step():
    s = springs.chain(8, k=1e4, total_mass=0.1)
    x, v = s.rest_state()
    with pytest.raises(SimulationDiverged, match=r"blew up at step \d+ .*moved") as info:
        simulate(s, x, v, dt=0.005, n_steps=40)
    assert info.value.step < 15 and np.abs(info.value.result.x).max() < 1e6


def test_free_fall_is_not_a_blow_up():
    s = springs.SpringSystem([[0.0, 0.0], [1.0, 0.0]], [[0, 1]], k=10.0)
    x, v = s.rest_state()
    r = simulate(s, x, v, dt=0.01, n_steps=5000)           # 50 s: falls 12 km, legitimately
    assert r.x[-1, 0, 1] < -1e4


X2 = [[0.0, 0.0], [1.0, 0.0]]
SPRING_CASES = [
    (dict(damping=float("nan")), ValueError, r"damping γ \(1/s\) must be finite"),
    (dict(damping=-1.0), ValueError, r"damping γ \(1/s\) must be >= 0"),
    (dict(damping="a"), TypeError, r"damping γ \(1/s\) must be a number"),
    (dict(gravity=(0.0, float("nan"))), ValueError, r"gravity must be finite"),
    (dict(gravity=(0.0, 1.0, 2.0)), ValueError, r"gravity must have 2 components"),
    (dict(ground=0.0, ground_stiffness=-5.0), ValueError, r"ground_stiffness must be >= 0"),
    (dict(ground_stiffness=float("inf")), ValueError, r"ground_stiffness must be finite"),
    (dict(ground=float("nan")), ValueError, r"ground \(height\) must be finite"),
    (dict(k=float("nan")), ValueError, r"k must be finite and >= 0"),
    (dict(k=-3.0), ValueError, r"k must be finite and >= 0"),
    (dict(mass=-1.0), ValueError, r"masses must be finite and >= 0"),
    (dict(mass=float("nan")), ValueError, r"masses must be finite"),
    (dict(mass=[1.0, 2.0, 3.0]), ValueError, r"mass must be a scalar or shape \(2,\)"),
    (dict(fixed=[5]), ValueError, r"fixed refers to particles outside 0\.\.1"),
    (dict(edges=[[0, 2]]), ValueError, r"edge \(0, 2\) refers to a particle"),
    (dict(edges=[[0, 0]]), ValueError, r"joins a particle to itself"),
    (dict(X=[[0.0, np.nan], [1, 0]]), ValueError, r"X contains NaN"),
    (dict(spring_damping=-1.0), ValueError, r"spring_damping must be finite and >= 0"),
]


@pytest.mark.parametrize("kw, exc, match", SPRING_CASES)
def test_spring_system_parameters_are_checked_when_built(kw, exc, match):
    args = dict(X=X2, edges=[[0, 1]], k=10.0)
    args.update(kw)
    with pytest.raises(exc, match=match):
        springs.SpringSystem(**args)


S = springs.chain(3, k=10.0, total_mass=1.0)
X0, V0 = S.rest_state()
SIM_CASES = [
    (lambda: simulate(S, X0, V0, dt=0.0, n_steps=3), r"dt must be"),
    (lambda: simulate(S, X0, V0, dt=float("nan"), n_steps=3), r"dt must be"),
    (lambda: simulate(S, X0, V0, dt=0.01, n_steps=-1), r"n_steps must be a non-negative"),
    (lambda: simulate(S, X0, V0, dt=0.01, n_steps=2.5), r"n_steps must be a non-negative"),
    (lambda: simulate(S, X0, V0, dt=0.01, n_steps=float("inf")), r"n_steps must be"),
    (lambda: simulate(S, X0, V0, dt=1e-9, n_steps=10**9), r"limit of 50,000,000"),
    (lambda: simulate(S, X0[:2], V0, dt=0.01, n_steps=3), r"x0 must have shape"),
    (lambda: simulate(S, X0, V0[:, :1], dt=0.01, n_steps=3), r"v0 must have the same shape"),
    (lambda: simulate(S, X0 * np.nan, V0, dt=0.01, n_steps=3), r"x0 .*NaN|x0 .*finite"),
    (lambda: simulate(S, X0, V0, dt=0.01, n_steps=3, method="rk9"), r"rk9"),
    (lambda: integrate(lambda t, y: -y, [1.0], (0.0, 1.0), 0.0), r"dt must be"),
    (lambda: integrate(lambda t, y: -y, [1.0], (1.0, 0.0), 0.1), r"t_span"),
    (lambda: integrate(lambda t, y: -y, [np.nan], (0.0, 1.0), 0.1), r"NaN|finite"),
]


@pytest.mark.parametrize("call, match", SIM_CASES)
def test_integrator_arguments_are_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("E, nu, match", [
    (float("nan"), 0.3, r"must be finite"), (1e3, float("nan"), r"must be finite"),
    (float("inf"), 0.3, r"must be finite"), (-1.0, 0.3, r"Young's modulus must be > 0"),
    (1e3, 0.5, r"Poisson ratio must lie in"), (1e3, -1.0, r"Poisson ratio must lie in"),
])
def test_lame_parameters_are_checked(E, nu, match):
    with pytest.raises(ValueError, match=match):
        fem.lame_parameters(E, nu)


MESH = grid_mesh(3, 3, 30.0, 30.0)
BODY = pa.Body(MESH)


def _scene(**kw):
    return pa.Scene([BODY], **kw)


SCENE_CASES = [
    (lambda: _scene(restitution=5.0), ValueError, r"restitution must be <= 1"),
    (lambda: _scene(restitution=-0.1), ValueError, r"restitution must be >= 0"),
    (lambda: _scene(friction=float("nan")), ValueError, r"friction must be finite"),
    (lambda: _scene(friction=-1.0), ValueError, r"friction must be >= 0"),
    (lambda: _scene(damping=-1.0), ValueError, r"damping must be >= 0"),
    (lambda: _scene(damping=float("nan")), ValueError, r"damping must be finite"),
    (lambda: _scene(gravity=(0.0, float("nan"))), ValueError, r"gravity must be finite"),
    (lambda: _scene(gravity=(1.0,)), ValueError, r"gravity must have 2 components"),
    (lambda: _scene(walls=(10.0, 5.0)), ValueError, r"x_min < x_max"),
    (lambda: _scene(ground=float("inf")), ValueError, r"ground must be finite"),
    (lambda: _scene(size=(0, 10)), ValueError, r"size must be \(W, H\)"),
    (lambda: _scene(collisions="yes"), TypeError, r"collisions must be True or False"),
    (lambda: pa.Scene([]), ValueError, r"at least one body"),
    (lambda: pa.Scene([MESH]), TypeError, r"bodies\[0\] must be a Body"),
    (lambda: pa.Material(E=float("nan")), ValueError, r"Material E .* must be finite"),
    (lambda: pa.Material(nu=0.5), ValueError, r"Material nu .* must be < 0\.5"),
    (lambda: pa.Material(rho=0.0), ValueError, r"Material rho .* must be > 0"),
    (lambda: pa.Body(MESH, velocity=(np.nan, 0)), ValueError, r"Body velocity must be finite"),
    (lambda: pa.Body(MESH, texture=np.zeros((4, 4))), ValueError, r"Body texture must be"),
    (lambda: pa.EnergyStroke([[0.0, 0.0], [np.nan, 5.0]]), ValueError,
     r"stroke points must be finite, point 1"),
    (lambda: pa.EnergyStroke([[0.0, 0.0], [5.0, 5.0]], strength=float("inf")), ValueError,
     r"stroke strength must be finite"),
    (lambda: pa.EnergyStroke([[0.0, 0.0], [5.0, 5.0]], range=0.0), ValueError,
     r"stroke range \(px\) must be > 0"),
    (lambda: pa.EnergyStroke([[0.0, 0.0], [5.0, 5.0]], kind="storm"), ValueError,
     r"unknown stroke kind 'storm'"),
    (lambda: pa.EnergyStroke([[0.0, 0.0], [5.0, 5.0]], n_particles=0), ValueError,
     r"n_particles must be >= 1"),
    (lambda: pa.EnergyStroke([[0.0, 0.0], [5.0, 5.0]], direction=(0.0, 0.0)), ValueError,
     r"non-zero vector"),
    (lambda: pa.FixedRig(center=(1.0, 1.0)), ValueError, r"needs either vertices or center"),
    (lambda: pa.FixedRig(center=(np.nan, 1.0), radius=3.0), ValueError,
     r"FixedRig center must be finite"),
    (lambda: pa.FixedRig(body=-1, vertices=(0,)), ValueError, r"body \(index\) must be >= 0"),
    (lambda: pa.WavyRig(vertices=(0,), frequency=float("nan")), ValueError,
     r"WavyRig frequency .* must be finite"),
    (lambda: pa.simulate(_scene(), duration=float("inf")), ValueError, r"duration .* finite"),
    (lambda: pa.simulate(_scene(), duration=-1.0), ValueError, r"duration \(s\) must be > 0"),
    (lambda: pa.simulate(_scene(), duration=1.0, fps=0), ValueError, r"fps must be > 0"),
    (lambda: pa.simulate(_scene(), duration=1e6, dt=1e-6), ValueError, r"limit of 10,000,000"),
]


@pytest.mark.parametrize("call, exc, match", SCENE_CASES)
def test_scene_parameters_are_checked_when_built(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


# ----------------------------------------------------------------------------- Scene JSON
def _scene_dict():
    img = np.zeros((4, 4, 4), np.uint8)
    sc = pa.Scene([pa.Body(MESH, texture=img)],
                  strokes=[pa.EnergyStroke([[0.0, 0.0], [20.0, 5.0]])],
                  rigs=[pa.FixedRig(center=(0.0, 0.0), radius=5.0),
                        pa.WavyRig(vertices=(3,), amplitude=4.0)], gravity=(0.0, 980.0))
    return json.loads(sc.to_json())


def _mutated(**changes):
    d = _scene_dict()
    for path, value in changes.items():
        obj, keys = d, path.split(".")
        for k in keys[:-1]:
            obj = obj[int(k)] if k.isdigit() else obj[k]
        last = keys[-1]
        if value is DELETE:
            del obj[int(last) if last.isdigit() else last]
        else:
            obj[int(last) if last.isdigit() else last] = value
    return json.dumps(d)


DELETE = object()


def _put(path, content):
    (path.write_bytes if isinstance(content, bytes) else path.write_text)(content)
    return path


JSON_CASES = [
    (lambda p: _put(p, _mutated()[:200]), r"s\.json: not valid JSON .*truncated"),
    (lambda p: _put(p, _mutated(rigs=DELETE)), None),           # optional: default
    (lambda p: _put(p, _mutated(bodies=DELETE)), r"s\.json: field scene lacks 'bodies'"),
    (lambda p: _put(p, _mutated(**{"bodies.0.X": DELETE})),
     r"s\.json: field bodies\[0\] lacks 'X'"),
    (lambda p: _put(p, _mutated(friction="high")),
     r"s\.json: field scene: friction must be a number"),
    (lambda p: _put(p, _mutated(friction=float("nan"))),
     r"s\.json: field scene: friction must be finite"),
    (lambda p: _put(p, _mutated(restitution=5)), r"restitution must be <= 1"),
    (lambda p: _put(p, _mutated(**{"rigs.0.type": "Spring"})),
     r"field rigs\[0\]\.type: unknown rig kind 'Spring'"),
    (lambda p: _put(p, _mutated(**{"strokes.0.kind": "storm"})),
     r"field strokes\[0\]: unknown stroke kind 'storm'"),
    (lambda p: _put(p, _mutated(**{"strokes.0.colour": "red"})),
     r"field strokes\[0\] has unknown key\(s\) 'colour'"),
    (lambda p: _put(p, _mutated(**{"bodies.0.texture": "bm90IGEgcG5n"})),
     r"field bodies\[0\]\.texture: texture is not a valid base64 PNG"),
    (lambda p: _put(p, _mutated(**{"bodies.0.tris": [[0, 1]]})),
     r"field bodies\[0\]\.X/tris: tris must have shape"),
    (lambda p: _put(p, _mutated(**{"bodies.0.material.E": -5})),
     r"field bodies\[0\]: Material E .* must be > 0"),
    (lambda p: _put(p, _mutated(rigs={"a": 1})), r"field rigs must be a JSON list"),
    (lambda p: _put(p, "[1, 2]"), r"field scene must be a JSON object, got list"),
    (lambda p: _put(p, b"\xff\xfe\x00bin"), r"not a text file"),
]


@pytest.mark.parametrize("make, match", JSON_CASES)
def test_scene_from_json_names_file_and_field(tmp_path, make, match):
    path = make(tmp_path / "s.json")
    if match is None:
        assert isinstance(pa.Scene.from_json(path), pa.Scene)
        return
    with pytest.raises(ValueError, match=match):
        pa.Scene.from_json(path)


def test_scene_from_json_text_and_paths():
    text = _mutated()
    assert pa.Scene.from_json(text).gravity == (0.0, 980.0)
    with pytest.raises(ValueError, match=r"scene JSON: field scene must be a JSON object"):
        pa.Scene.from_json("[1, 2, 3]")                   # JSON, not a path
    with pytest.raises(FileNotFoundError, match=r"no scene file nowhere\.json"):
        pa.Scene.from_json("nowhere.json")
    with pytest.raises(TypeError, match=r"JSON text or a file path"):
        pa.Scene.from_json(42)


_GOOD = _scene_dict()
_LEAVES = []


def _walk(obj, path=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            _walk(v, path + (k,))
    elif isinstance(obj, list) and obj and not isinstance(obj[0], (int, float)):
        for i, v in enumerate(obj[:2]):
            _walk(v, path + (i,))
    else:
        _LEAVES.append(path)


_walk(_GOOD)
_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True),
                    st.text(max_size=4), st.lists(st.floats(-10, 10), max_size=3),
                    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


@settings(max_examples=200, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(_LEAVES), st.one_of(st.just(DELETE), _VALUES)),
                min_size=1, max_size=3))
def test_scene_from_json_fuzz_only_clear_errors(edits):
    import copy

    d = copy.deepcopy(_GOOD)
    for path, value in edits:
        obj = d
        try:
            for k in path[:-1]:
                obj = obj[k]
            if value is DELETE:
                del obj[path[-1]]
            else:
                obj[path[-1]] = value
        except (KeyError, IndexError, TypeError):
            continue                                # an earlier edit removed the parent
    try:
        sc = pa.Scene.from_json(json.dumps(d))
    except ValueError as e:
        assert str(e).startswith("scene JSON: "), e
        return
    assert isinstance(sc, pa.Scene)
    assert np.isfinite(sc.friction) and 0 <= sc.restitution <= 1
