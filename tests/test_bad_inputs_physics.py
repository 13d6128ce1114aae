"""Bad input to the physics half (integrators, springs, FEM, PhysAnimator scenes): each case
raises an error that blames the right cause — the argument or field, never "use a smaller
dt" for a NaN parameter — and a blow-up is caught by its growth, not only by NaN."""
import json

import numpy as np
import pytest

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
    (dict(damping=float("nan")), ValueError, r"damping γ \(N·s/m\) must be finite"),
    (dict(damping=-1.0), ValueError, r"damping γ \(N·s/m\) must be >= 0"),
    (dict(damping="a"), TypeError, r"damping γ \(N·s/m\) must be a number"),
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
class _Driven:
    """One particle at the origin pushed by ``sin t`` (N): at rest with no force at t = 0."""
    mass = np.array([1.0])

    def force(self, x, v, t):
        return np.array([[np.sin(t), 0.0]])


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
    (lambda: simulate(S, X0, V0, 0.01, 3, save_every=0), r"save_every must be an integer >= 1"),
    (lambda: simulate(S, X0, V0, 0.01, 3, save_every=float("nan")), r"save_every must be"),
    (lambda: simulate(S, X0, V0, 0.01, 3, method="implicit_euler", max_iter=0),
     r"max_iter must be an integer >= 1, got 0"),
    (lambda: simulate(S, X0, V0, 0.01, 3, tol=-1.0), r"tol must be a finite number >= 0"),
    (lambda: simulate(S, X0, V0, 0.01, 3, atol=float("nan")), r"atol must be a finite number"),
    (lambda: simulate(S, X0, V0, 0.01, 3, t0=float("inf")), r"t0 \(start time\) must be a finite"),
    (lambda: simulate(S, X0, V0, 0.01, 3, max_speed=0.0), r"max_speed must be > 0"),
    (lambda: simulate(S, [[0.0, 1.0], [2.0]], V0, 0.01, 3), r"x0 must be a numeric array"),
    (lambda: simulate(springs.cloth_grid(100, 100), *springs.cloth_grid(100, 100).rest_state(),
                      1e-4, 40_000_000), r"simulate: storing 80,000,002 states .* GB, more than "
                                         r"the limit .*save_every"),
    (lambda: integrate(lambda t, y: -y, [1.0], (0.0, 1e12), 1e-3),
     r"t_span \(0, 1e\+12\) at dt = 0\.001 is .* steps, more than the limit of 50,000,000"),
    (lambda: integrate(lambda t, y: "a", [1.0], (0.0, 1.0), 0.1), r"f\(t, y\) must return numbers"),
    (lambda: integrate(lambda t, y: -y, [1.0], (0.0, 1.0), 0.1, method="implicit_euler",
                       tol=float("nan")), r"tol must be a finite number >= 0, got nan"),
]


@pytest.mark.parametrize("call, match", SIM_CASES)
def test_integrator_arguments_are_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("call, match", [
    (lambda: simulate(S, X0, V0, dt=0.01, n_steps="3"), r"n_steps must be an integer, got '3'"),
    (lambda: simulate(S, X0, V0, dt="a", n_steps=3), r"dt must be a number, got 'a'"),
    (lambda: simulate(object(), X0, V0, dt=0.01, n_steps=3), r"system must have 'mass' and "
                                                             r"'force'.* has no 'mass'"),
    (lambda: simulate(S, X0, V0, 0.01, 3, project="yes"), r"project must be None or a function"),
    (lambda: integrate("f", [1.0], (0.0, 1.0), 0.1), r"f must be a function"),
])
def test_integrator_argument_types_are_named(call, match):
    with pytest.raises(TypeError, match=match):
        call()


def test_a_force_that_starts_later_is_not_a_blow_up():
    # x ≈ t - sin t: 1000 m after 1000 s, far beyond what x0 = v0 = a0 = 0 "allow", but
    # growing like a power of time, not exponentially
    r = simulate(_Driven(), np.zeros((1, 2)), np.zeros((1, 2)), 0.01, 100_000)
    assert r.x[-1, 0, 0] == pytest.approx(1000.0 - np.sin(1000.0), rel=1e-2)


def test_max_speed_is_a_blow_up_with_the_partial_run():
    # semi-implicit Euler: v_k = 1 + dt Σ_{j<k} sin(j dt) first exceeds 1.01 at step k
    vx = 1 + 0.01 * np.cumsum(np.sin(0.01 * np.arange(500)))
    k = int(np.argmax(vx > 1.01)) + 1
    with pytest.raises(SimulationDiverged, match=rf"step {k} .*speed of 1\.01 exceeds "
                                                 rf"max_speed = 1\.01") as info:
        simulate(_Driven(), np.zeros((1, 2)), np.ones((1, 2)), 0.01, 500, max_speed=1.01)
    assert info.value.step == k and info.value.result.x.shape == (k, 1, 2)
    assert np.all(np.abs(info.value.result.v) <= 1.01)


MESH = grid_mesh(3, 3, 30.0, 30.0)
BODY = pa.Body(MESH)

BUILDER_CASES = [
    (lambda: springs.chain(1), ValueError, r"n_particles must be >= 2, got 1"),
    (lambda: springs.chain(2.5), ValueError, r"n_particles must be a whole number, got 2\.5"),
    (lambda: springs.chain(3, length=float("nan")), ValueError, r"length \(m\) must be finite"),
    (lambda: springs.chain(3, total_mass=-1.0), ValueError, r"total_mass \(kg\) must be > 0"),
    (lambda: springs.chain(3, anchor=(0.0,)), ValueError, r"anchor must have 2 components"),
    (lambda: springs.cloth_grid(100_000, 100_000), ValueError,
     r"a cloth of 100000 × 100000 = 10,000,000,000 particles is more than the limit of "
     r"1,000,000"),
    (lambda: springs.cloth_grid(3, 3, dim=4), ValueError, r"dim must be 2 or 3, got 4"),
    (lambda: springs.soft_box(0, 4), ValueError, r"soft box nx must be >= 2, got 0"),
    (lambda: springs.soft_box(size=0.0), ValueError, r"size \(m\) must be > 0"),
    (lambda: springs.hanging_spring(L=-1.0), ValueError, r"L \(rest length, m\) must be > 0"),
    (lambda: springs.hanging_spring(m=0.0), ValueError, r"m \(mass, kg\) must be > 0"),
    (lambda: springs.SpringSystem(X2, [[0, 1]], k=1.0, fixed=[0.5]), ValueError,
     r"fixed must hold integer particle indices"),
    (lambda: springs.SpringSystem("ab", [[0, 1]], k=1.0), ValueError,
     r"X \(rest positions\) must be an \(n, 2\) or \(n, 3\) array of numbers"),
    (lambda: springs.SpringSystem(X2, [["a", "b"]], k=1.0), ValueError,
     r"edges must be an \(E, 2\) array of particle indices"),
    (lambda: springs.SpringSystem(X2, [[0, 1]], k=1.0, gravity="down"), ValueError,
     r"gravity must be a number or an array of numbers"),
    (lambda: fem.lame_parameters("soft", 0.3), TypeError,
     r"Young's modulus E must be a number or an array of numbers, got 'soft'"),
    (lambda: fem.lame_parameters(1e3, 0.3, plane="3d"), ValueError,
     r"plane must be 'strain' or 'stress', got '3d'"),
    (lambda: fem.rest_shape(MESH.X * np.nan, MESH.tris), ValueError,
     r"X \(rest positions\) must be finite, vertex 0"),
    (lambda: fem.lumped_masses(MESH.X, MESH.tris, float("nan")), ValueError,
     r"density rho must be finite"),
    (lambda: fem.lumped_masses(MESH.X, MESH.tris, np.ones(3)), ValueError,
     r"density rho must be a scalar or shape \(18,\) \(one per triangle\)"),
    (lambda: fem.CorotatedFEM(MESH.X, MESH.tris, float("nan"), 1.0), ValueError,
     r"mu \(Lamé μ\) must be finite"),
    (lambda: fem.CorotatedFEM(MESH.X, MESH.tris, -1.0, 1.0), ValueError,
     r"mu \(Lamé μ\) must be >= 0"),
    (lambda: fem.stable_time_step(MESH.X, MESH.tris, 1e3, 0.3, 0.0), ValueError,
     r"density rho must be > 0"),
    (lambda: fem.stable_time_step(MESH.X, MESH.tris, 1e3, 0.3, 1.0, safety=2.0), ValueError,
     r"safety must be a number in \(0, 1\], got 2\.0"),
]


@pytest.mark.parametrize("call, exc, match", BUILDER_CASES)
def test_builders_and_fem_name_the_argument(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


@pytest.mark.parametrize("E, nu, match", [
    (float("nan"), 0.3, r"must be finite"), (1e3, float("nan"), r"must be finite"),
    (float("inf"), 0.3, r"must be finite"), (-1.0, 0.3, r"Young's modulus must be > 0"),
    (1e3, 0.5, r"Poisson ratio must lie in"), (1e3, -1.0, r"Poisson ratio must lie in"),
])
def test_lame_parameters_are_checked(E, nu, match):
    with pytest.raises(ValueError, match=match):
        fem.lame_parameters(E, nu)




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
    (lambda: pa.simulate("scene.json", 1.0), TypeError,
     r"scene must be a physlab\.physanimator\.Scene, got str \(load JSON with Scene\.from_json\)"),
    (lambda: pa.simulate(_scene(), 1.0, method="rk4"), ValueError, r"unknown method 'rk4'"),
    (lambda: pa.simulate(pa.Scene([pa.Body(grid_mesh(200, 200, 400.0, 400.0))]), 1000.0,
                         fps=1000), ValueError,
     r"1,000,001 frames of 40,401 vertices need .* GB, more than the limit .*lower fps"),
    (lambda: pa.safe_time_step(_scene(), safety=0.0), ValueError, r"safety must be > 0"),
    (lambda: pa.measured_stable_dt(_scene(), rel_tol=0.0), ValueError,
     r"rel_tol must be >= 1e-06, got 0"),
    (lambda: pa.Scene(BODY), TypeError, r"bodies must be a list, got Body \(wrap a single Body"),
    (lambda: _scene(strokes=None), TypeError, r"strokes must be a list, got NoneType"),
    (lambda: _scene(ground=10.0), ValueError, r"bodies\[0\] \('body'\) starts below the "
                                              r"ground \(y = 30 px > ground = 10 px"),
    (lambda: _scene(walls=(5.0, 100.0)), ValueError, r"bodies\[0\] \('body'\) starts outside "
                                                     r"the walls"),
    (lambda: _scene(rigs=[pa.FixedRig(vertices=(100,))]), ValueError,
     r"rigs\[0\] \(on body 0, 'body'\): rig vertex 100 is outside 0\.\.15"),
    (lambda: _scene(rigs=[pa.FixedRig(center=(500.0, 500.0), radius=2.0)]), ValueError,
     r"rigs\[0\] .*selects no vertex; move it onto the body"),
    (lambda: _scene(rigs=[pa.FixedRig(body=1, vertices=(0,))]), ValueError,
     r"rigs\[0\] refers to body 1, but the scene has 1"),
    (lambda: pa.FixedRig(vertices=()), ValueError, r"FixedRig vertices is empty"),
    (lambda: pa.FixedRig(vertices=(-1,)), ValueError, r"FixedRig vertices must be indices >= 0"),
    (lambda: pa.FixedRig(center=(1e9, 0.0), radius=1.0), ValueError,
     r"FixedRig center must lie within ±1e\+07 px"),
    (lambda: pa.WavyRig(vertices=(0,), direction=(0.0, 0.0)), ValueError,
     r"WavyRig direction must be a non-zero vector"),
    (lambda: pa.Body(MESH, offset=(1e8, 0.0)), ValueError,
     r"Body vertices must lie within ±1e\+07 px .*reaches 1e\+08 px"),
    (lambda: pa.Body(MESH, name=3), TypeError, r"Body name must be a string, got 3"),
    (lambda: pa.Body((np.array([[0.0, 0.0], [1e300, 0.0], [0.0, 1.0]]), np.array([[0, 1, 2]]))),
     ValueError, r"mesh X must lie within ±1e\+07 px"),
    (lambda: pa.EnergyStroke("ab"), ValueError, r"stroke points must be a \(k, 2\) list"),
    (lambda: pa.EnergyStroke([[0.0, 0.0], [2e7, 0.0]]), ValueError,
     r"stroke points must lie within ±1e\+07 px, point 1"),
    (lambda: pa.wind_force((0, 0), MESH.X, (1, 0), float("nan"), 5.0), ValueError,
     r"s \(strength\) must be finite"),
    (lambda: pa.wind_force((0, 0), MESH.X, (1, 0), 1.0, float("inf")), ValueError,
     r"r \(influence range, px\) must be finite"),
    (lambda: pa.wind_force((0, 0), MESH.X, (0, 0), 1.0, 5.0), ValueError,
     r"d \(wind direction\) must be a non-zero vector"),
    (lambda: pa.repel_force((0, 0, 0), MESH.X, 1.0, 5.0), ValueError,
     r"p \(particle position\) must have 2 components"),
    (lambda: pa.attract_force((0, 0), MESH.X[:, :1], 1.0, 5.0), ValueError,
     r"q \(vertices\) must have shape \(n, 2\)"),
    (lambda: pa.flow_force("storm", (0, 0), MESH.X, 1.0, 5.0), ValueError,
     r"unknown flow particle kind 'storm'"),
    (lambda: pa.wavy_rig_position((0, 0), 1.0, 1.0, (0, 0), 0.0), ValueError,
     r"d_r \(direction\) must be a non-zero vector"),
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
    with pytest.raises(ValueError, match=r"scene JSON: not valid JSON .*nested too deeply"):
        pa.Scene.from_json("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ValueError, match=r"scene JSON: field scene must be a JSON object, got int"):
        pa.Scene.from_json("42")


def test_a_file_name_starting_with_a_digit_is_a_path(tmp_path, monkeypatch):
    (tmp_path / "2024_scene.json").write_text(_mutated())
    monkeypatch.chdir(tmp_path)
    assert pa.Scene.from_json("2024_scene.json").gravity == (0.0, 980.0)
    (tmp_path / "7.json").write_text("{}")
    with pytest.raises(ValueError, match=r"^7\.json: field scene lacks 'bodies'"):
        pa.Scene.from_json("7.json")


def test_a_physanimator_blow_up_is_a_simulation_diverged_with_the_frames_before_it():
    sc = pa.Scene([pa.Body(MESH, pa.Material(E=4e6), offset=(100.0, 100.0))],
                  gravity=(0.0, 980.0))
    dt = 20 * pa.safe_time_step(sc)
    with pytest.warns(UserWarning, match="stability estimate"):
        with pytest.raises(SimulationDiverged, match=r"blew up at step \d+ .*use dt <=") as info:
            pa.simulate(sc, 0.5, dt=dt, fps=1 / dt, progress=False)
    err = info.value
    assert isinstance(err, pa.UnstableTimeStep) and err.dt == dt and err.step >= 1
    assert isinstance(err.result, pa.Animation) and err.result.n_frames == err.step
    assert np.all(np.isfinite(err.result.x[0])) and err.result.x[0].shape == (err.step, 16, 2)


@pytest.mark.parametrize("kw, cause, advice", [
    (dict(damping=1e7, gravity=(0.0, 980.0)),
     r"damping 1e\+07/s × dt = 1e\+04 \(explicit steps need damping·dt < 2\)", r"use dt <= 1e-07 s"),
    (dict(gravity=(0.0, 1e11)), r"gravity 1e\+11 px/s² moves vertices 1e\+05 px per step",
     r"dt is already within the stability estimate"),
    (dict(strokes=[pa.EnergyStroke([[90.0, 110.0], [140.0, 110.0]], strength=1e16)]),
     r"strokes\[0\] \(strength 1e\+16\) accelerates the lightest vertex",
     r"dt is already within the stability estimate"),
])
def test_a_blow_up_names_the_scene_parameter_that_caused_it(kw, cause, advice):
    import warnings

    sc = pa.Scene([pa.Body(MESH, offset=(100.0, 100.0))], **kw)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(pa.UnstableTimeStep, match=r"likely causes: " + cause + ".*" + advice):
            pa.simulate(sc, 0.05, dt=1e-3, progress=False)
    # dt is only warned about when it is above the estimate (here: the damping limit)
    assert bool(caught) == ("damping" in kw)
